"""The settings logic of the RealSense colour sensor, on the SDK's own objects: choosing the
colour mode, locking exposure, gain and white balance through the sensor's options, reading
each frame's metadata, and turning the factory intrinsics into OpenCV's model.

``rs`` is the ``pyrealsense2`` module (:func:`drivers.realsense.sdk.rs`), passed in so this
module imports nothing of the SDK itself.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field

import numpy as np

from armstereo.camera_model import Intrinsics
from armstereo.errors import ConfigError

log = logging.getLogger(__name__)

SET_ABS_TOL = 1e-3  # options read back within this (they are integers on the colour sensor)
# Mount vs device intrinsics: beyond these the mount is not this camera's (or not this mode's).
INTRINSICS_FOCAL_REL_TOL = 0.01
INTRINSICS_CENTRE_TOL_PX = 5.0
DISTORTION_FIT_GRID = 21  # samples per image axis when fitting OpenCV's model (see below)


@dataclass(frozen=True)
class Mode:
    """A colour stream mode: size, frame rate and pixel format (``bgr8``, ``rgb8``)."""

    width: int
    height: int
    fps: int
    format: str

    def label(self) -> str:
        return f"{self.width}x{self.height}@{self.fps} {self.format}"


@dataclass
class Locked:
    """What :func:`lock_options` did: the values read back (armstereo.camera_settings
    names), the automatic modes turned off, and what could not be set."""

    settings: dict[str, float] = field(default_factory=dict)
    auto_off: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)


def colour_profiles(rs, sensor) -> list:
    """The sensor's colour video profiles in BGR8 or RGB8 (what armstereo converts)."""
    out = []
    for p in sensor.get_stream_profiles():
        if p.stream_type() == rs.stream.color and p.format() in (rs.format.bgr8, rs.format.rgb8):
            out.append(p.as_video_stream_profile())
    return out


def mode_of(rs, profile) -> Mode:
    fmt = "bgr8" if profile.format() == rs.format.bgr8 else "rgb8"
    return Mode(profile.width(), profile.height(), profile.fps(), fmt)


def choose_profile(rs, profiles: list, size: tuple[int, int] | None, fps: int,
                   preferred_size: tuple[int, int] | None, camera: str):
    """The colour profile to stream: ``size`` (asked for) or else ``preferred_size`` (the
    mount's) if offered, else the largest; at ``fps``; BGR8 before RGB8. ConfigError listing
    the modes otherwise."""
    modes = [(mode_of(rs, p), p) for p in profiles]
    if not modes:
        raise ConfigError(f"{camera} has no colour stream in BGR8 or RGB8")
    at_fps = [(m, p) for m, p in modes if m.fps == fps]
    offered = ", ".join(sorted({m.label() for m, _ in modes}))
    if not at_fps:
        raise ConfigError(f"{camera} has no colour mode at {fps} fps (--fps; modes: {offered})")
    if size is not None:
        chosen = [(m, p) for m, p in at_fps if (m.width, m.height) == tuple(size)]
        if not chosen:
            raise ConfigError(f"{camera} has no {size[0]}x{size[1]} colour mode at {fps} fps "
                              f"(modes: {offered})")
    else:
        chosen = [(m, p) for m, p in at_fps if (m.width, m.height) == tuple(preferred_size or ())]
        if not chosen:
            largest = max(m.width * m.height for m, _ in at_fps)
            chosen = [(m, p) for m, p in at_fps if m.width * m.height == largest]
    chosen.sort(key=lambda mp: mp[0].format != "bgr8")
    return chosen[0][1]


def lock_options(rs, sensor, camera: str, *, exposure: float | None, gain: float | None,
                 white_balance: float | None) -> Locked:
    """Auto exposure and auto white balance off; exposure, gain and white balance set where
    asked (ConfigError when the sensor lacks the option, cannot change it, e.g. a playback,
    or the value is out of range); everything read back."""
    rep = Locked()
    o = rs.option
    for auto in (o.enable_auto_exposure, o.enable_auto_white_balance):
        if sensor.supports(auto) and sensor.get_option(auto) != 0:
            if sensor.is_option_read_only(auto):
                rep.notes.append(f"{auto.name} is on and read-only")
                continue
            sensor.set_option(auto, 0.0)
            rep.auto_off.append(auto.name)
    for opt, value, flag in ((o.exposure, exposure, "--exposure"), (o.gain, gain, "--gain"),
                             (o.white_balance, white_balance, "--white-balance")):
        if value is None:
            continue
        if not sensor.supports(opt):
            raise ConfigError(f"{camera} has no {opt.name} option, so {flag} cannot be set")
        if sensor.is_option_read_only(opt):
            raise ConfigError(f"{camera}: {opt.name} is read-only (a playback replays what was "
                              f"recorded), so {flag} {value:g} cannot be set")
        r = sensor.get_option_range(opt)
        if not r.min <= value <= r.max:
            raise ConfigError(f"{flag} {value:g} is outside {camera}'s {opt.name} range "
                              f"{r.min:g}..{r.max:g}")
        sensor.set_option(opt, float(value))
        got = sensor.get_option(opt)
        if abs(got - value) > SET_ABS_TOL + (r.step or 0):
            rep.notes.append(f"{opt.name} set to {value:g} reads back {got:g}")
    rep.settings = read_options(rs, sensor)
    return rep


def read_options(rs, sensor) -> dict[str, float]:
    """Exposure, gain and white balance as the sensor's options read now."""
    out = {}
    for opt, name in ((rs.option.exposure, "exposure"), (rs.option.gain, "gain"),
                      (rs.option.white_balance, "white_balance_k")):
        if sensor.supports(opt):
            out[name] = float(sensor.get_option(opt))
    return out


def frame_report(rs, frame) -> tuple[dict[str, float], int | None, int | None]:
    """(settings, device time stamp ns, frame number) of one frame from its metadata: the
    exposure, gain and white balance the camera says it used for this very frame."""
    md = rs.frame_metadata_value
    settings = {}
    for key, name in ((md.actual_exposure, "exposure"), (md.gain_level, "gain"),
                      (md.white_balance, "white_balance_k")):
        if frame.supports_frame_metadata(key):
            settings[name] = float(frame.get_frame_metadata(key))
    stamp = None
    if frame.supports_frame_metadata(md.frame_timestamp):
        stamp = int(frame.get_frame_metadata(md.frame_timestamp)) * 1000  # us on the device
    elif frame.get_frame_timestamp_domain() == rs.timestamp_domain.hardware_clock:
        stamp = int(round(frame.get_timestamp() * 1e6))  # ms on the device's clock
    number = int(frame.get_frame_number())
    return settings, stamp if stamp is None or stamp >= 0 else None, \
        number if number >= 0 else None


def to_intrinsics(rs, intr) -> tuple[Intrinsics, str]:
    """The SDK's ``rs.intrinsics`` as :class:`Intrinsics` (OpenCV's model) and a note on the
    conversion. Brown-Conrady is OpenCV's model (same coefficient order k1, k2, p1, p2, k3).
    For Inverse Brown-Conrady (the D400 colour sensors' model) OpenCV's forward coefficients
    are fitted by least squares to the SDK's own deprojection of a grid of pixels, so OpenCV
    maps rays to the pixels the SDK says they come from (the fit's worst residual is in the
    note). Other models (fisheye ones) raise ConfigError: give a calibrated mount (--mount)."""
    K = np.array([[intr.fx, 0.0, intr.ppx], [0.0, intr.fy, intr.ppy], [0.0, 0.0, 1.0]])
    coeffs = np.array(list(intr.coeffs)[:5], dtype=float)
    model = intr.model
    if model == rs.distortion.none or not np.any(coeffs):
        return Intrinsics(intr.width, intr.height, K, np.zeros(5)), "no distortion"
    if model in (rs.distortion.brown_conrady, rs.distortion.modified_brown_conrady):
        return Intrinsics(intr.width, intr.height, K, coeffs), f"{model.name} coefficients"
    if model == rs.distortion.inverse_brown_conrady:
        u, v = np.meshgrid(np.linspace(0, intr.width - 1, DISTORTION_FIT_GRID),
                           np.linspace(0, intr.height - 1, DISTORTION_FIT_GRID))
        pixels = np.stack([u.ravel(), v.ravel()], axis=1)
        rays = np.array([rs.rs2_deproject_pixel_to_point(intr, [float(a), float(b)], 1.0)
                         for a, b in pixels])
        dist, worst_px = fit_forward_distortion(K, rays[:, :2] / rays[:, 2:], pixels)
        return Intrinsics(intr.width, intr.height, K, dist), \
            f"inverse_brown_conrady fitted to OpenCV's model (worst {worst_px:.3f} px)"
    raise ConfigError(f"the camera's colour intrinsics use the {model.name} distortion model, "
                      "which armstereo does not convert; give a calibrated mount (--mount "
                      "FILE, --realsense-intrinsics mount)")


def _brown(x: np.ndarray, y: np.ndarray, c: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """OpenCV's distortion with coefficients (k1, k2, p1, p2, k3) on normalised points."""
    r2 = x * x + y * y
    f = 1 + c[0] * r2 + c[1] * r2 ** 2 + c[4] * r2 ** 3
    return (x * f + 2 * c[2] * x * y + c[3] * (r2 + 2 * x * x),
            y * f + 2 * c[3] * x * y + c[2] * (r2 + 2 * y * y))


def fit_forward_distortion(K: np.ndarray, ideal: np.ndarray,
                           pixels: np.ndarray) -> tuple[np.ndarray, float]:
    """OpenCV distortion (k1, k2, p1, p2, k3) mapping the normalised ``ideal`` points (N, 2)
    to ``pixels`` (N, 2) through ``K``, and its worst residual (px). The model's displacement
    is linear in its coefficients, so one least-squares solve fits it."""
    xd = (pixels[:, 0] - K[0, 2]) / K[0, 0]
    yd = (pixels[:, 1] - K[1, 2]) / K[1, 1]
    xu, yu = ideal[:, 0], ideal[:, 1]
    r2 = xu * xu + yu * yu
    # xd - xu = xu (k1 r2 + k2 r4 + k3 r6) + 2 p1 xu yu + p2 (r2 + 2 xu^2), and alike for y
    ax = np.stack([xu * r2, xu * r2 ** 2, 2 * xu * yu, r2 + 2 * xu * xu, xu * r2 ** 3], axis=1)
    ay = np.stack([yu * r2, yu * r2 ** 2, r2 + 2 * yu * yu, 2 * xu * yu, yu * r2 ** 3], axis=1)
    dist = np.linalg.lstsq(np.vstack([ax, ay]), np.concatenate([xd - xu, yd - yu]),
                           rcond=None)[0]
    fx, fy = _brown(xu, yu, dist)
    worst = float(np.max(np.hypot((fx - xd) * K[0, 0], (fy - yd) * K[1, 1])))
    return dist, worst


def cross_check(device: Intrinsics, mount: Intrinsics) -> list[str]:
    """How the mount's intrinsics disagree with the device's factory calibration (empty when
    within INTRINSICS_FOCAL_REL_TOL and INTRINSICS_CENTRE_TOL_PX), one line each."""
    out = []
    if device.size != mount.size:
        return [f"the mount's intrinsics are for {mount.width}x{mount.height}, the stream is "
                f"{device.width}x{device.height}"]
    for name, a, b in (("fx", device.K[0, 0], mount.K[0, 0]), ("fy", device.K[1, 1],
                                                              mount.K[1, 1])):
        if abs(b - a) > INTRINSICS_FOCAL_REL_TOL * a:
            out.append(f"{name} {b:.1f} px in the mount, {a:.1f} px in the device "
                       f"({(b - a) / a * 100:+.1f} %)")
    for name, a, b in (("cx", device.K[0, 2], mount.K[0, 2]), ("cy", device.K[1, 2],
                                                              mount.K[1, 2])):
        if abs(b - a) > INTRINSICS_CENTRE_TOL_PX:
            out.append(f"{name} {b:.1f} px in the mount, {a:.1f} px in the device")
    return out


def device_info(rs, device) -> dict[str, str]:
    """Serial, name, firmware and USB link of an ``rs.device``, where it tells them."""
    out = {}
    for key, name in ((rs.camera_info.serial_number, "serial"), (rs.camera_info.name, "name"),
                      (rs.camera_info.firmware_version, "firmware"),
                      (rs.camera_info.usb_type_descriptor, "usb")):
        try:
            if device.supports(key):
                out[name] = str(device.get_info(key))
        except RuntimeError:
            continue
    return out
