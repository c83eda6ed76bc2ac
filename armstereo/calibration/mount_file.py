"""Write a calibrated camera mount in the TOML format ``armstereo.mount`` reads, and grade it.

Numbers are written with Python's shortest round-trip repr, so reading the file back gives
bit-identical floats; the rotation goes in as ``rotation_matrix`` (no Euler-angle round trip).
"""

from __future__ import annotations

import math
import re

import numpy as np

from armstereo.calibration.poses import pose_difference
from armstereo.camera_model import Intrinsics
from armstereo.errors import ConfigError
from armstereo.mount import CameraMount
from armstereo.photometric.vignetting import Vignetting

_NAME_RE = re.compile(r"^[A-Za-z0-9_.\-]+$")


def mount_toml(name: str, T_flange_camera: np.ndarray, intrinsics: Intrinsics,
               comments: list[str] | None = None, vignetting: Vignetting | None = None) -> str:
    """TOML text of a mount (``armstereo.mount`` format) with optional ``#`` comment lines
    and, when given, the ``[vignetting]`` section."""
    if not _NAME_RE.match(name):
        raise ConfigError(f"mount name {name!r} may only use letters, digits, '_', '-', '.'")
    T = np.asarray(T_flange_camera, dtype=float)
    R, t = T[:3, :3], T[:3, 3]
    K = intrinsics.K
    lines = [f"# {c}" for c in (comments or [])]
    lines += [
        f'name = "{name}"',
        "",
        "[hand_eye]",
        "# T_flange_camera: pose of the camera_optical frame (x right, y down, z forward) in "
        "tool0.",
        f"translation = {_vec(t)}",
        f"rotation_matrix = [{', '.join(_vec(row) for row in R)}]",
        "",
        "[camera]",
        f"width = {int(intrinsics.width)}",
        f"height = {int(intrinsics.height)}",
        f"K = [{', '.join(_vec(row) for row in K)}]",
        f"dist = {_vec(intrinsics.dist)}",
        "",
    ]
    if vignetting is not None:
        lines += vignetting.toml_lines()
    return "\n".join(lines)


def _vec(v) -> str:
    return "[" + ", ".join(_num(x) for x in np.asarray(v, dtype=float).reshape(-1)) + "]"


def _num(x: float) -> str:
    if not math.isfinite(x):
        raise ConfigError(f"cannot write a non-finite number ({x}) to a mount file")
    return repr(float(x))


def truth_error(mount: CameraMount, true_mount: CameraMount) -> dict:
    """How far a calibrated mount is from the truth (simulations):
    ``{"translation_m", "rotation_deg", "focal_rel"}``; focal_rel is the signed relative error
    of the mean focal length (fx + fy) / 2. When both have a vignetting model, also
    ``vignetting_corner_rel``: the largest relative error of the fall-off at the four image
    corners (estimated V over true V, minus 1)."""
    dt, dr = pose_difference(mount.T_flange_camera, true_mount.T_flange_camera)
    f = (mount.intrinsics.fx + mount.intrinsics.fy) / 2
    f_true = (true_mount.intrinsics.fx + true_mount.intrinsics.fy) / 2
    out = {"translation_m": dt, "rotation_deg": dr, "focal_rel": f / f_true - 1.0}
    if mount.vignetting is not None and true_mount.vignetting is not None:
        rel = mount.vignetting.corner_gains() / true_mount.vignetting.corner_gains() - 1.0
        out["vignetting_corner_rel"] = float(rel[np.argmax(np.abs(rel))])
    return out
