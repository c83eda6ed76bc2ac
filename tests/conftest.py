"""Shared pytest setup: the ``hardware`` marker runs only when a robot address is given."""

from __future__ import annotations

import pytest


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
