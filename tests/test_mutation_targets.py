"""bench/mutation.py names the functions it mutates: a rename must not silently shrink what
mutation testing covers (docs/testing.md §4)."""

from __future__ import annotations

import pytest

from bench import mutation as MUTATION
from tests.support import ROOT


@pytest.mark.parametrize("target", MUTATION.TARGETS, ids=lambda t: t.name)
def test_every_named_definition_exists_and_its_tests_too(target):
    MUTATION.check_definitions(target)
    for test in target.tests:
        assert (ROOT / test).is_file(), test


def test_a_renamed_definition_is_reported():
    renamed = MUTATION.Target("plan", "armstereo/capture/plan.py", (), ("_check_speed",))
    with pytest.raises(SystemExit, match="_check_speed"):
        MUTATION.check_definitions(renamed)
