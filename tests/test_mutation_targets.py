"""bench/mutation.py names the functions it mutates: a rename must not silently shrink what
mutation testing covers (docs/testing.md §4)."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def load_mutation_module():
    spec = importlib.util.spec_from_file_location("bench_mutation", ROOT / "bench" / "mutation.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # dataclasses look their module up there
    spec.loader.exec_module(module)
    return module


MUTATION = load_mutation_module()


@pytest.mark.parametrize("target", MUTATION.TARGETS, ids=lambda t: t.name)
def test_every_named_definition_exists_and_its_tests_too(target):
    MUTATION.check_definitions(target)
    for test in target.tests:
        assert (ROOT / test).is_file(), test


def test_a_renamed_definition_is_reported():
    renamed = MUTATION.Target("plan", "armstereo/capture/plan.py", (), ("_check_speed",))
    with pytest.raises(SystemExit, match="_check_speed"):
        MUTATION.check_definitions(renamed)
