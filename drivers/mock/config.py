"""Configs of the mock arm and mock camera (registry names ``mock``); their fields' metadata
are the command-line flags (see :mod:`armstereo.backends`)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

from armstereo.backends import option
from armstereo.errors import ConfigError
from drivers.mock.faults import FAULTS, FaultPlan

_FAULT_HELP = ("mock backends only: inject a fault (" + ", ".join(FAULTS) + "; N = which move "
               "or grab, default 2); repeatable")


@dataclass(frozen=True, kw_only=True)
class MockArmConfig:
    """The simulated arm. ``layout`` picks the start pose the mock scene is laid out for
    (``table``: camera 0.55 m above the table looking down; ``horizontal``: looking across it);
    ``q0`` (6 joints, rad) overrides it."""

    layout: str = "table"
    q0: tuple[float, ...] | None = None
    realtime: bool = field(default=False, metadata=option(
        "--realtime", "mock arm: move in real time instead of simulated time",
        action="store_true"))
    joint_noise: float = field(default=0.0, metadata=option(
        "--joint-noise", "mock arm: joint repeatability noise, rad", type=float))
    seed: int = field(default=0, metadata=option(
        "--seed", "seed for the mock backends' noise", type=int))
    faults: tuple[str, ...] = field(default=(), metadata=option(
        "--inject-fault", _FAULT_HELP, action="append", metavar="NAME[@N]"))

    def __post_init__(self) -> None:
        _check_nonnegative("--joint-noise", self.joint_noise, "rad")
        object.__setattr__(self, "faults", tuple(self.faults))
        FaultPlan.parse(self.faults)  # names and counts checked now, before anything moves

    @property
    def fault_plan(self) -> FaultPlan:
        return FaultPlan.parse(self.faults)

    @staticmethod
    def injects(fault: str) -> bool:
        """True for the faults the mock arm injects (those counted in moves)."""
        return fault in FAULTS and FAULTS[fault][0] == "move"


@dataclass(frozen=True, kw_only=True)
class MockCameraConfig:
    """The ray-cast camera. ``scene`` (a :class:`drivers.mock.scene.Scene`) replaces the
    default table scene."""

    scene: Any = None
    noise: float = field(default=0.0, metadata=option(
        "--camera-noise", "mock camera: sensor noise sigma in grey levels", type=float))
    seed: int = field(default=0, metadata=option(
        "--seed", "seed for the mock backends' noise", type=int))
    faults: tuple[str, ...] = field(default=(), metadata=option(
        "--inject-fault", _FAULT_HELP, action="append", metavar="NAME[@N]"))

    def __post_init__(self) -> None:
        _check_nonnegative("--camera-noise", self.noise, "grey levels")
        object.__setattr__(self, "faults", tuple(self.faults))
        FaultPlan.parse(self.faults)

    @property
    def fault_plan(self) -> FaultPlan:
        return FaultPlan.parse(self.faults)

    @staticmethod
    def injects(fault: str) -> bool:
        """True for the faults the mock camera injects (those counted in grabs)."""
        return fault in FAULTS and FAULTS[fault][0] == "grab"


def _check_nonnegative(flag: str, value: float, unit: str) -> None:
    if not (isinstance(value, int | float) and math.isfinite(value) and value >= 0):
        raise ConfigError(f"{flag} must be a finite number >= 0 {unit}, got {value!r}")
