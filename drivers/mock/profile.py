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
- ``hand_eye``: the camera's true ``T_flange_camera`` differs from the bundled mount file's
  by a seeded error the size of a CAD drawing's (a few mm, about a degree).
- ``intrinsics``: true focal lengths and principal point differ from the bundled mount file's
  datasheet values by a few percent and pixels, and the lens has radial distortion the file
  does not know.
- ``residual``: the arm's pose error its controller's calibration leaves (a tenth of a
  millimetre, varying with the joints) and its repeatability.
- ``image``: photon and read noise, defocus blur, vignetting, and a small exposure and white
  balance change between views.
- ``board``: what a printed calibration board adds (print scale error, a board that is not
  flat, glare on its laminate).

A profile and a seed are one physical cell (:mod:`drivers.mock.cell`): every command that runs
on the mock (calibrate, capture, scan, sweep, demo) sees the same arm, the same camera and the
same table. On ``realistic`` the camera is the cell's own, whatever mount file the software is
given; on ``ideal`` it is exactly the mount file the software uses.
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
TAG_VIGNETTING = 15
TAG_RESIDUAL = 16
TAG_REPEAT = 17
TAG_BOARD = 18


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
    two radial distortion terms (k1, k2), about ``radial_mean``."""

    focal_rel: float = 0.0
    principal_px: float = 0.0
    radial: float = 0.0
    # The lens's own radial distortion (k1, k2) added to the mount file's: a datasheet mount
    # says "no distortion", the lens has some.
    radial_mean: tuple[float, float] = (0.0, 0.0)


@dataclass(frozen=True)
class ImageEffects:
    """What a real sensor and lens do to an image. ``read_noise`` grey levels and
    ``shot_noise_gain`` (variance per grey level: photon noise); ``blur_sigma_px`` Gaussian
    defocus; ``vignetting``: relative brightness lost at the image corners (mean over cells;
    each cell's lens draws its own fall-off about it, :func:`drivers.mock.cell.true_vignetting`);
    ``exposure_rel`` and ``white_balance_rel``: standard deviation of the per-view overall gain
    and of each channel's extra gain."""

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
class ArmResidual:
    """What is left of the arm's pose error once its controller's calibrated kinematics are
    used (one standard deviation per axis, flange frame): a smooth function of the joints
    (``translation_m``, ``rotation_rad``: gear and elastic errors no DH table holds) and a fresh
    error after every move (``repeat_m``, ``repeat_rad``: repeatability)."""

    translation_m: float = 0.0
    rotation_rad: float = 0.0
    repeat_m: float = 0.0
    repeat_rad: float = 0.0

    @property
    def any(self) -> bool:
        return any(v > 0 for v in (self.translation_m, self.rotation_rad, self.repeat_m,
                                   self.repeat_rad))


@dataclass(frozen=True)
class BoardErrors:
    """What a printed calibration board adds: the print's scale error (one standard
    deviation, relative: squares that much larger than the spec says), how far the board
    bows (sag of its centre against its corners, m, one standard deviation) and the glare of
    its laminate (Blinn-Phong highlight strength, share of full white; 0 = matte paper)."""

    scale_rel: float = 0.0
    bow_m: float = 0.0
    glare: float = 0.0
    glare_shininess: float = 60.0


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
    residual: ArmResidual = field(default_factory=ArmResidual)
    board: BoardErrors = field(default_factory=BoardErrors)
    # True: the camera is the cell's own (the bundled mount with the hand-eye and intrinsics
    # errors), whatever mount file the software uses; False: exactly the software's mount.
    cell_camera: bool = False


IDEAL = MockProfile("ideal")
REALISTIC = MockProfile(
    "realistic", kinematics=True,
    joints=JointErrors(encoder_noise_rad=1e-5, settle_amplitude_rad=2e-4),
    hand_eye=HandEyeErrors(translation_m=2.5e-3, rotation_rad=math.radians(0.6)),
    intrinsics=IntrinsicsErrors(focal_rel=0.02, principal_px=5.0, radial=0.02,
                                radial_mean=(-0.10, 0.05)),
    image=ImageEffects(read_noise=1.5, shot_noise_gain=0.03, blur_sigma_px=0.7, vignetting=0.25,
                       exposure_rel=0.02, white_balance_rel=0.01),
    scene="desk",
    residual=ArmResidual(translation_m=5e-5, rotation_rad=5e-5, repeat_m=1e-5,
                         repeat_rad=1e-5),
    board=BoardErrors(scale_rel=0.002, bow_m=0.0005, glare=0.6, glare_shininess=600.0),
    cell_camera=True)
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
