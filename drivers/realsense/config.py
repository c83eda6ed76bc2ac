"""Config of the RealSense camera backend (registry name ``realsense:<serial>``); its fields'
metadata are the command-line flags (``--exposure``, ``--gain``, ``--white-balance`` and
``--resolution`` are shared with the OpenCV camera). Importing it needs no SDK."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

from armstereo.errors import ConfigError
from armstereo.flags import option
from armstereo.validate import positive, whole
from drivers.opencv.config import parse_resolution

INTRINSICS_SOURCES = ("auto", "device", "mount")
PLAYBACK_SUFFIXES = (".bag", ".db3")
MAX_FPS = 300


@dataclass(frozen=True, kw_only=True)
class RealSenseCameraConfig:
    """The colour stream of an Intel RealSense camera.

    ``device``: its serial number (``armstereo cameras`` lists them). ``playback``: play this
    SDK recording (``.bag``, ``.db3``) instead of a live camera; its device's serial must be
    ``device``. ``resolution`` (width, height) and ``fps`` choose the colour mode (default:
    the mount's size if the camera has it, else its largest, at 30 fps). ``exposure`` and
    ``gain`` (the SDK's units for the colour sensor) and ``white_balance`` (kelvin) are locked
    with auto exposure and auto white balance off; None keeps and locks the current value.
    ``intrinsics``: ``device`` (the factory calibration stored in the camera), ``mount`` (the
    mount file's, cross-checked against the device's), ``auto`` (the device's unless a mount
    file other than the bundled default is given).
    """

    device: str
    playback: str | None = field(default=None, metadata=option(
        "--realsense-playback", "RealSense camera: play this SDK recording (.bag or .db3) "
        "instead of a live camera", metavar="FILE"))
    resolution: tuple[int, int] | None = field(default=None, metadata=option(
        "--resolution", "OpenCV, GenICam or RealSense camera: WIDTHxHEIGHT to ask for",
        metavar="WxH"))
    fps: int = field(default=30, metadata=option(
        "--fps", "RealSense camera: colour stream frame rate", type=int))
    exposure: float | None = field(default=None, metadata=option(
        "--exposure", "OpenCV or RealSense camera: exposure, locked (the backend's units)",
        type=float))
    gain: float | None = field(default=None, metadata=option(
        "--gain", "OpenCV or RealSense camera: gain, locked (the backend's units)", type=float))
    white_balance: float | None = field(default=None, metadata=option(
        "--white-balance", "OpenCV or RealSense camera: white balance in kelvin, locked",
        type=float))
    intrinsics: str = field(default="auto", metadata=option(
        "--realsense-intrinsics", "RealSense camera: device (factory calibration), mount "
        "(the mount file's, checked against the device's) or auto (device unless --mount is "
        "given)",
        choices=INTRINSICS_SOURCES))
    timeout: float = 5.0

    def __post_init__(self) -> None:
        if not str(self.device).strip():
            raise ConfigError("the RealSense camera needs a serial number: realsense:<serial> "
                              "(armstereo cameras lists them)")
        object.__setattr__(self, "device", str(self.device).strip())
        if self.playback is not None:
            path = Path(self.playback)
            if path.suffix.lower() not in PLAYBACK_SUFFIXES:
                raise ConfigError(f"--realsense-playback {path}: expected an SDK recording "
                                  f"({', '.join(PLAYBACK_SUFFIXES)})")
            if not path.is_file():
                raise ConfigError(f"--realsense-playback {path}: no such file")
        object.__setattr__(self, "resolution", parse_resolution(self.resolution))
        whole(self.fps, "--fps", 1, MAX_FPS)
        for flag, value in (("--exposure", self.exposure), ("--gain", self.gain)):
            if value is not None and not (math.isfinite(value) and value >= 0):
                raise ConfigError(f"{flag} must be a finite number >= 0, got {value!r}")
        if self.white_balance is not None:
            positive(self.white_balance, "--white-balance", "K")
        if self.intrinsics not in INTRINSICS_SOURCES:
            raise ConfigError(f"--realsense-intrinsics must be one of "
                              f"{', '.join(INTRINSICS_SOURCES)}, got {self.intrinsics!r}")
        positive(self.timeout, "camera timeout", "s")
