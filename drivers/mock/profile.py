"""How far the mock world is from what the software believes: named, seeded error profiles.

``ideal`` is the exact mock every exactness test relies on: the arm moves with the very
kinematics the software uses, the camera has exactly the mount file's intrinsics and hand-eye
transform, images are clean ray-cast renders of the matcher-friendly table scene.

``realistic`` errs like real hardware, one group of error sources at a time so a benchmark can
switch them on one by one (``dataclasses.replace``; see bench/error_budget.py):

- ``kinematics``: the arm's TRUE kinematics are a seeded factory calibration
  (:func:`armstereo.robot.synthetic.synthetic_calibration`: 1-10 mm, 0.3-1 deg from nominal at
  the flange), which the arm broadcasts like a controller (:mod:`drivers.mock.broadcast`).
- ``joints``: every joint reading carries encoder noise, and after a move the joints ring
  with a small decaying oscillation (what ``wait_until_steady`` and the settle time wait out).
- ``hand_eye``: the camera's true ``T_flange_camera`` differs from the mount file's by a
  seeded error the size of a good hand-eye calibration's (about 1 mm, 0.1 deg per axis).
- ``intrinsics``: true focal lengths, principal point and distortion differ from the mount
  file's by a good calibration's residuals (0.3 %, 1.5 px, 0.01).
- ``image``: photon and read noise, defocus blur, vignetting, and a small exposure and white
  balance change between views.
- ``scene``: ``desk`` (photographed wood, brick, gravel and paper, a plain low-texture table
  top, a repetitive pattern, glossy objects whose highlights move between views) instead of
  ``table`` (band-limited textures made for the matcher).

Every random draw comes from ``numpy.random.default_rng([seed, TAG])`` with a tag per group,
so switching one group on or off never changes the others' draws.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from armstereo.errors import ConfigError
from armstereo.transforms import make_T, rotvec_to_matrix

# Tags of the random streams (one per error group).
TAG_JOINTS = 11
TAG_HAND_EYE = 12
TAG_INTRINSICS = 13
TAG_IMAGE = 14


@dataclass(frozen=True)
class JointErrors:
    """Encoder noise (rad, Gaussian, per joint and reading) and the ringing after a move:
    ``amplitude`` rad at the end of the move, decaying with ``time_constant`` s, at
    ``frequency`` Hz (UR arms ring at a few Hz after a stop)."""

    encoder_noise_rad: float = 0.0
    settle_amplitude_rad: float = 0.0
    settle_time_constant_s: float = 0.15
    settle_frequency_hz: float = 6.0

    @property
    def any(self) -> bool:
        return self.encoder_noise_rad > 0 or self.settle_amplitude_rad > 0


@dataclass(frozen=True)
class HandEyeErrors:
    """One standard deviation per axis of the true hand-eye transform's error (camera frame):
    translation in m, rotation in rad."""

    translation_m: float = 0.0
    rotation_rad: float = 0.0


@dataclass(frozen=True)
class IntrinsicsErrors:
    """One standard deviation of the true intrinsics' differences from the mount file:
    relative focal length (fx, fy each), principal point (px, cx and cy each), and the first
    two radial distortion terms (k1, k2)."""

    focal_rel: float = 0.0
    principal_px: float = 0.0
    radial: float = 0.0


@dataclass(frozen=True)
class ImageEffects:
    """What a real sensor and lens do to an image. ``read_noise`` grey levels and
    ``shot_noise_gain`` (variance per grey level: photon noise); ``blur_sigma_px`` Gaussian
    defocus; ``vignetting``: relative brightness lost at the image corners (cos^4-like
    falloff); ``exposure_rel`` and ``white_balance_rel``: standard deviation of the per-view
    overall gain and of each channel's extra gain."""

    read_noise: float = 0.0
    shot_noise_gain: float = 0.0
    blur_sigma_px: float = 0.0
    vignetting: float = 0.0
    exposure_rel: float = 0.0
    white_balance_rel: float = 0.0

    @property
    def any(self) -> bool:
        return any(v > 0 for v in (self.read_noise, self.shot_noise_gain, self.blur_sigma_px,
                                   self.vignetting, self.exposure_rel, self.white_balance_rel))


@dataclass(frozen=True)
class MockProfile:
    """A named set of error sources (see the module doc). ``kinematics``: the arm's true
    kinematics are a seeded factory calibration (else exactly the software's model)."""

    name: str
    kinematics: bool = False
    joints: JointErrors = field(default_factory=JointErrors)
    hand_eye: HandEyeErrors = field(default_factory=HandEyeErrors)
    intrinsics: IntrinsicsErrors = field(default_factory=IntrinsicsErrors)
    image: ImageEffects = field(default_factory=ImageEffects)
    scene: str = "table"


IDEAL = MockProfile("ideal")
REALISTIC = MockProfile(
    "realistic", kinematics=True,
    joints=JointErrors(encoder_noise_rad=1e-5, settle_amplitude_rad=2e-4),
    hand_eye=HandEyeErrors(translation_m=1e-3, rotation_rad=math.radians(0.1)),
    intrinsics=IntrinsicsErrors(focal_rel=0.003, principal_px=1.5, radial=0.01),
    image=ImageEffects(read_noise=1.5, shot_noise_gain=0.03, blur_sigma_px=0.7, vignetting=0.25,
                       exposure_rel=0.02, white_balance_rel=0.01),
    scene="desk")
PROFILES = {p.name: p for p in (IDEAL, REALISTIC)}
PROFILE_NAMES = tuple(PROFILES)
SCENES = ("table", "desk")


def get_profile(name: str | MockProfile) -> MockProfile:
    """The profile called ``name`` (a MockProfile passes through); ConfigError otherwise."""
    if isinstance(name, MockProfile):
        if name.scene not in SCENES:
            raise ConfigError(f"mock profile {name.name!r}: unknown scene {name.scene!r}")
        return name
    if name not in PROFILES:
        raise ConfigError(f"unknown mock profile {name!r}; choose one of: "
                          f"{', '.join(PROFILE_NAMES)}")
    return PROFILES[name]


def rng_for(seed: int, tag: int) -> np.random.Generator:
    """The random stream of one error group (independent of the other groups)."""
    return np.random.default_rng([int(seed), int(tag)])


def parse_offset(text: str | tuple | None) -> tuple[float, ...] | None:
    """``dx,dy,dz,rx,ry,rz`` (metres, degrees) -> a 6-tuple, or None for none/empty."""
    if text is None or (isinstance(text, str) and not text.strip()):
        return None
    try:
        values = tuple(float(v) for v in (text.split(",") if isinstance(text, str) else text))
    except (TypeError, ValueError):
        values = ()
    if len(values) != 6 or not all(math.isfinite(v) for v in values):
        raise ConfigError(f"--mock-hand-eye-offset must be dx,dy,dz,rx,ry,rz (metres, "
                          f"degrees), got {text!r}")
    return values


def offset_transform(offset: tuple[float, ...] | None) -> np.ndarray:
    """4x4 ``T_camera_truecamera`` of an offset (dx, dy, dz m; rx, ry, rz deg, a rotation
    vector), both in the camera frame; identity for None."""
    if offset is None:
        return np.eye(4)
    return make_T(rotvec_to_matrix(np.radians(offset[3:])), offset[:3])


def hand_eye_error(errors: HandEyeErrors, seed: int) -> np.ndarray:
    """4x4 seeded error transform ``T_camera_truecamera`` (camera frame) of a profile."""
    rng = rng_for(seed, TAG_HAND_EYE)
    unit = rng.standard_normal(6)  # both drawn always: one source on or off keeps the other
    return make_T(rotvec_to_matrix(errors.rotation_rad * unit[3:]),
                  errors.translation_m * unit[:3])
