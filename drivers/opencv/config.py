"""Config of the OpenCV camera backend (registry name ``opencv:<device>``)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from armstereo.errors import ConfigError
from armstereo.flags import option


def parse_resolution(text: str | tuple[int, int] | None) -> tuple[int, int] | None:
    """``"WxH"`` (or a (W, H) pair) as two positive ints; None stays None."""
    if text is None or isinstance(text, tuple):
        return text
    w, _, h = str(text).lower().partition("x")
    if not (w.isdigit() and h.isdigit() and int(w) > 0 and int(h) > 0):
        raise ConfigError(f"--resolution must be WIDTHxHEIGHT in pixels, e.g. 1280x720, "
                          f"not {text!r}")
    return int(w), int(h)


@dataclass(frozen=True, kw_only=True)
class OpenCVCameraConfig:
    """An OpenCV VideoCapture device: ``device`` is an index, a path or a GStreamer pipeline.

    ``exposure``, ``gain`` and ``white_balance`` (Kelvin) are in the backend's units and locked
    for the whole capture; None keeps (and locks) what the device uses now. ``resolution``
    (width, height) asks the device for that mode; the mount's intrinsics are scaled to it
    (same aspect ratio). ``backend`` names OpenCV's capture API (v4l2, gstreamer, ...).
    """

    device: str
    exposure: float | None = field(default=None, metadata=option(
        "--exposure", "OpenCV camera: exposure, locked (backend units; default: keep the "
        "device's current value)", type=float))
    gain: float | None = field(default=None, metadata=option(
        "--gain", "OpenCV camera: gain, locked (backend units)", type=float))
    white_balance: float | None = field(default=None, metadata=option(
        "--white-balance", "OpenCV camera: white balance in Kelvin, locked", type=float))
    resolution: tuple[int, int] | None = field(default=None, metadata=option(
        "--resolution", "OpenCV camera: WIDTHxHEIGHT to request (intrinsics are scaled to it)",
        metavar="WxH"))
    backend: str | None = field(default=None, metadata=option(
        "--camera-backend", "OpenCV camera: capture API (any, v4l2, gstreamer, ffmpeg, ...)"))
    timeout: float = 2.0

    def __post_init__(self) -> None:
        if not str(self.device).strip():
            raise ConfigError("the OpenCV camera needs a device: opencv:<index, path or "
                              "pipeline>")
        for flag, value in (("--exposure", self.exposure), ("--gain", self.gain),
                            ("--white-balance", self.white_balance)):
            if value is not None and not math.isfinite(value):
                raise ConfigError(f"{flag} must be a finite number, got {value!r}")
        if self.white_balance is not None and self.white_balance <= 0:
            raise ConfigError(f"--white-balance must be > 0 K, got {self.white_balance!r}")
        object.__setattr__(self, "resolution", parse_resolution(self.resolution))
        if not (math.isfinite(self.timeout) and self.timeout > 0):
            raise ConfigError(f"camera timeout must be positive seconds, got {self.timeout!r}")
