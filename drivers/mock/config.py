"""Configs of the mock arm and mock camera (registry names ``mock``); their fields' metadata
are the command-line flags (see :mod:`armstereo.backends`)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from armstereo.flags import option
from armstereo.validate import non_negative, whole
from drivers.mock.faults import FAULTS, FaultPlan
from drivers.mock.profile import PROFILE_NAMES, get_profile, parse_offset

MAX_JOINT_NOISE_RAD = 0.01  # far beyond any arm's repeatability (UR: ~3e-5 rad)
MAX_CAMERA_NOISE = 64.0  # grey levels; beyond this the image is mostly noise
MAX_SEED = 2**32 - 1

_FAULT_HELP = ("mock backends only: inject a fault (" + ", ".join(FAULTS) + "; N = which move "
               "or grab, default 2); repeatable")
_PROFILE_HELP = ("mock backends: how far the mock world is from what the software believes: "
                 "ideal (exact) or realistic (factory-calibrated arm, encoder noise, camera "
                 "calibration errors, image effects, a desk scene); see docs/mock-profiles.md")


@dataclass(frozen=True, kw_only=True)
class _MockShared:
    """What the mock arm and mock camera share: one seed, one fault list (each backend injects
    the faults of its own kind) and one profile; the flags are given once for both."""

    _FAULT_KIND = ""  # "move" (arm) or "grab" (camera)

    seed: int = field(default=0, metadata=option(
        "--seed", "seed for the mock backends' noise", type=int))
    faults: tuple[str, ...] = field(default=(), metadata=option(
        "--inject-fault", _FAULT_HELP, action="append", metavar="NAME[@N]"))
    profile: Any = field(default="ideal", metadata=option(
        "--mock-profile", _PROFILE_HELP, choices=PROFILE_NAMES))

    def __post_init__(self) -> None:
        whole(self.seed, "--seed", 0, MAX_SEED)
        object.__setattr__(self, "profile", get_profile(self.profile))
        object.__setattr__(self, "faults", tuple(self.faults))
        FaultPlan.parse(self.faults)  # names and counts checked now, before anything moves

    @property
    def fault_plan(self) -> FaultPlan:
        return FaultPlan.parse(self.faults)

    @classmethod
    def injects(cls, fault: str) -> bool:
        """True for the faults this backend injects (the arm counts moves, the camera grabs)."""
        return fault in FAULTS and FAULTS[fault][0] == cls._FAULT_KIND


@dataclass(frozen=True, kw_only=True)
class MockArmConfig(_MockShared):
    """The simulated arm. ``layout`` picks the start pose the mock scene is laid out for
    (``table``: camera 0.55 m above the table looking down; ``horizontal``: looking across it);
    ``q0`` (6 joints, rad) overrides it."""

    _FAULT_KIND = "move"

    layout: str = "table"
    q0: tuple[float, ...] | None = None
    realtime: bool = field(default=False, metadata=option(
        "--realtime", "mock arm: move in real time instead of simulated time",
        action="store_true"))
    joint_noise: float = field(default=0.0, metadata=option(
        "--joint-noise", "mock arm: joint repeatability noise, rad", type=float))

    def __post_init__(self) -> None:
        super().__post_init__()
        non_negative(self.joint_noise, "--joint-noise", "rad", cap=MAX_JOINT_NOISE_RAD)


@dataclass(frozen=True, kw_only=True)
class MockCameraConfig(_MockShared):
    """The ray-cast camera. ``scene`` (a :class:`drivers.mock.scene.Scene`) replaces the
    profile's scene. ``truth_mount`` (a CameraMount): the mount the profile's camera errors are
    applied to when it is not the one the software uses (a benchmark that hands the software a
    perfectly calibrated camera). ``board`` (an ``armstereo.calibration.board.Board``): lay
    that calibration board on the table, cleared of objects (``armstereo calibrate`` sets it)."""

    _FAULT_KIND = "grab"

    scene: Any = None
    truth_mount: Any = None
    board: Any = None
    noise: float = field(default=0.0, metadata=option(
        "--camera-noise", "mock camera: sensor noise sigma in grey levels", type=float))
    hand_eye_offset: Any = field(default=None, metadata=option(
        "--mock-hand-eye-offset", "mock camera: move its TRUE hand-eye transform by dx,dy,dz "
        "(m),rx,ry,rz (deg, a rotation vector), in the camera frame, on top of the profile's "
        "own error; the mount file stays as given"))

    def __post_init__(self) -> None:
        super().__post_init__()
        non_negative(self.noise, "--camera-noise", "grey levels", cap=MAX_CAMERA_NOISE)
        object.__setattr__(self, "hand_eye_offset", parse_offset(self.hand_eye_offset))
