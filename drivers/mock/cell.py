"""One simulated robot cell: what a mock profile and a seed fix for every command.

A user has one arm, one camera on its flange and one table. On the mock, ``--mock-profile``
and ``--seed`` name that set-up, and every command that runs on the mock backends
(``calibrate``, ``capture``, ``scan``, ``sweep``, ``demo``) meets the same one:

- the arm's true kinematics (its factory calibration, :mod:`drivers.mock.arm`) and what its
  controller's calibration leaves (:mod:`drivers.mock.residual`);
- the camera (:func:`cell_camera`): its true hand-eye transform, intrinsics and lens
  distortion, and its vignetting. On a profile with ``cell_camera`` (``realistic``) they are
  the bundled mount file's (:data:`REFERENCE_MOUNT`: a CAD hand-eye guess and datasheet
  intrinsics) moved by the profile's seeded errors, whatever mount file the software is given:
  a mount file written by ``armstereo calibrate`` on the cell is then right for the camera
  ``capture`` simulates. On ``ideal`` the camera is exactly the mount the software uses;
- the table and what stands on it (the profile's scene, textured by the seed).

Every draw comes from its own random stream (:func:`drivers.mock.profile.rng_for`), so one error
group switched off leaves the others as they were.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from armstereo.camera_model import Intrinsics
from armstereo.errors import ConfigError
from armstereo.mount import DEFAULT_MOUNT, CameraMount
from armstereo.photometric.vignetting import Vignetting
from drivers.mock.profile import (
    TAG_INTRINSICS,
    TAG_VIGNETTING,
    ImageEffects,
    IntrinsicsErrors,
    MockProfile,
    hand_eye_error,
    offset_transform,
    rng_for,
)

REFERENCE_MOUNT = DEFAULT_MOUNT  # the bundled mount file a cell's camera is built from
VIGNETTING_SPREAD = 0.1  # relative spread of the corner fall-off from cell to cell
R4_SHARE = (0.35, 0.1, 0.1, 0.6)  # mean, spread, min, max share of the r^4 term in the fall-off


@dataclass(frozen=True)
class CellCamera:
    """The cell's camera as it really is: ``mount`` (true ``T_flange_camera`` and intrinsics
    with lens distortion) and ``vignetting`` (its fall-off; None when the profile has none)."""

    mount: CameraMount
    vignetting: Vignetting | None

    def truth(self, profile: MockProfile, seed: int, offset=None) -> dict:
        """JSON-ready truth for a recording's ``mock_camera_truth``."""
        intr = self.mount.intrinsics
        return {"profile": profile.name, "seed": int(seed), "cell": cell_name(profile, seed),
                "T_flange_camera": self.mount.T_flange_camera.tolist(),
                "K": intr.K.tolist(), "dist": intr.dist.tolist(),
                "hand_eye_offset": list(offset or ()),
                "vignetting": None if self.vignetting is None else self.vignetting.as_dict()}


def cell_name(profile: MockProfile, seed: int) -> str:
    """How reports name a cell: ``realistic seed 0``."""
    return f"{profile.name} seed {int(seed)}"


def cell_camera(profile: MockProfile, seed: int, believed: CameraMount, *,
                reference: CameraMount | None = None, offset=None) -> CellCamera:
    """The cell's true camera (module doc). ``believed``: the mount the software uses;
    ``reference``: the mount the profile's errors are applied to instead of the cell's own
    (a benchmark that builds another camera); ``offset``: ``--mock-hand-eye-offset``.
    ConfigError when the software's mount is for another image size than the cell's camera."""
    base = reference
    if base is None:
        base = CameraMount.load(REFERENCE_MOUNT) if profile.cell_camera else believed
    if base.intrinsics.size != believed.intrinsics.size:
        w, h = base.intrinsics.size
        bw, bh = believed.intrinsics.size
        raise ConfigError(f"the mock cell's camera ({profile.name} profile) delivers {w}x{h} "
                          f"images, the mount file says {bw}x{bh}")
    mount = true_mount(base, profile, seed, offset)
    return CellCamera(mount, true_vignetting(profile.image, mount.intrinsics, seed))


def true_mount(mount: CameraMount, profile: MockProfile, seed: int, offset=None) -> CameraMount:
    """``mount`` moved by the profile's seeded errors: its hand-eye transform by the hand-eye
    error and ``offset`` (dx, dy, dz m, rx, ry, rz deg; camera frame), its intrinsics by the
    intrinsics errors (:func:`true_intrinsics`)."""
    T = (mount.T_flange_camera @ hand_eye_error(profile.hand_eye, seed)
         @ offset_transform(offset))
    return replace(mount, name=f"{mount.name} (true, {profile.name} seed {seed})",
                   T_flange_camera=T,
                   intrinsics=true_intrinsics(mount.intrinsics, profile.intrinsics, seed))


def true_intrinsics(believed: Intrinsics, errors: IntrinsicsErrors, seed: int) -> Intrinsics:
    """``believed`` with seeded errors of the sizes in ``errors`` (focal lengths relative,
    principal point in px, k1 and k2 about the lens's ``radial_mean``)."""
    unit = rng_for(seed, TAG_INTRINSICS).standard_normal(6)  # always drawn: reproducible
    K = believed.K.copy()
    K[0, 0] *= 1.0 + errors.focal_rel * unit[0]
    K[1, 1] *= 1.0 + errors.focal_rel * unit[1]
    K[0, 2] += errors.principal_px * unit[2]
    K[1, 2] += errors.principal_px * unit[3]
    dist = np.zeros(max(5, believed.dist.size))
    dist[:believed.dist.size] = believed.dist
    dist[0] += errors.radial_mean[0] + errors.radial * unit[4]
    dist[1] += errors.radial_mean[1] + errors.radial * unit[5]
    return Intrinsics(believed.width, believed.height, K, dist)


def true_vignetting(effects: ImageEffects, intrinsics: Intrinsics,
                    seed: int) -> Vignetting | None:
    """The lens's fall-off: ``V = 1 + k1 r^2 + k2 r^4`` about the true principal point, the
    corners (r = 1) ``effects.vignetting`` darker on average (spread VIGNETTING_SPREAD), the
    r^4 term's share of it seeded (R4_SHARE). None when the profile has no vignetting."""
    unit = rng_for(seed, TAG_VIGNETTING).standard_normal(2)  # always drawn
    if effects.vignetting <= 0:
        return None
    fall = effects.vignetting * (1.0 + VIGNETTING_SPREAD * unit[0])
    mean, spread, lo, hi = R4_SHARE
    share = float(np.clip(mean + spread * unit[1], lo, hi))
    return Vignetting(intrinsics.width, intrinsics.height, (intrinsics.cx, intrinsics.cy),
                      (-fall * (1.0 - share), -fall * share, 0.0))
