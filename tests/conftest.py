"""Shared pytest setup: the ``hardware`` marker runs only when a robot address is given, and
the Hypothesis profiles of the property tests."""

from __future__ import annotations

import os

import pytest
from hypothesis import HealthCheck, Phase, settings

# Property tests are regression tests here: every run (CI or not) draws the same examples
# (derandomized, no example database), so a failure reproduces and a pass means the same thing
# each time. Example counts are set per test to keep each file fast. No shrinking: examples
# cost up to a tenth of a second each, shrinking one took minutes, and the first failing
# example of a fixed sequence is already reproducible and printed. HYPOTHESIS_PROFILE=explore
# searches with fresh random examples and more of them (tests/support/properties.py), and
# shrinks what it finds, to hunt for new bugs.
settings.register_profile("repeatable", derandomize=True, database=None, deadline=None,
                          print_blob=True, suppress_health_check=[HealthCheck.too_slow],
                          phases=[Phase.explicit, Phase.generate])
settings.register_profile("explore", derandomize=False, database=None, deadline=None,
                          suppress_health_check=[HealthCheck.too_slow])
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "repeatable"))


def pytest_addoption(parser: pytest.Parser) -> None:
    parser.addoption("--ur-host", default=None,
                     help="IP of a real UR controller; enables tests marked 'hardware'")
    parser.addoption("--ur-model", default="ur5e", help="robot model of the --ur-host arm")
    parser.addoption("--ur-allow-motion", action="store_true", default=False,
                     help="let hardware tests move the arm (10 mm guarded move; clear workspace)")


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    if config.getoption("--ur-host"):
        return
    skip = pytest.mark.skip(reason="hardware test: pass --ur-host IP to run it against a real arm")
    for item in items:
        if "hardware" in item.keywords:
            item.add_marker(skip)


@pytest.fixture
def ur_host(request: pytest.FixtureRequest) -> str:
    """The real controller's address given with --ur-host."""
    return request.config.getoption("--ur-host")
