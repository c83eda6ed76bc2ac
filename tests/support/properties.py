"""Example counts of the Hypothesis property tests (profiles: tests/conftest.py)."""

from __future__ import annotations

import os

EXPLORE_FACTOR = 25  # HYPOTHESIS_PROFILE=explore draws this many times more examples


def examples(n: int) -> int:
    """``n`` examples in the repeatable (default) profile, ``n * EXPLORE_FACTOR`` when exploring."""
    return n * EXPLORE_FACTOR if os.environ.get("HYPOTHESIS_PROFILE") == "explore" else n
