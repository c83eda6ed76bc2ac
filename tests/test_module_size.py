"""Small modules with one job each: no module of ``armstereo`` or ``drivers`` is over 500 lines
(docstrings and comments count: a reader reads them too)."""

from __future__ import annotations

import pytest

from tests.support import ROOT

MAX_LINES = 500
FILES = sorted(p for package in ("armstereo", "drivers") for p in (ROOT / package).rglob("*.py"))


def test_the_scan_sees_the_packages():
    assert len(FILES) > 100


@pytest.mark.parametrize("path", FILES, ids=lambda p: str(p.relative_to(ROOT)))
def test_module_is_at_most_500_lines(path):
    name = str(path.relative_to(ROOT))
    lines = len(path.read_text().splitlines())
    assert lines <= MAX_LINES, f"{name} has {lines} lines (at most {MAX_LINES}): split it by job"
