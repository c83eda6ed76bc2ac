"""Which depths a pair is matched over: the disparity window.

The rectified right image is shifted so that the far end of the depth range has disparity 0,
so the matcher searches ``[0, max_disparity]``. With ``max_disparity="auto"`` the budget comes
from ``near``/``far`` (given, or guessed from the scene: the arm stands on its working surface,
the plane ``z = 0`` of ``base``), capped at :data:`MAX_AUTO_DISPARITY` labels.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, replace

import numpy as np

from armstereo.camera_model import Intrinsics
from armstereo.errors import ConfigError
from armstereo.reconstruct.rectified import StereoGeometry

log = logging.getLogger(__name__)

DEFAULT_NEAR_M = 0.3  # working range when the scene gives no hint
DEFAULT_FAR_M = 1.5
TABLE_FAR_MARGIN = 1.1  # far = this x the deepest table point seen
TABLE_NEAR_SHARE = 0.5  # near = this x the nearest table point (objects up to half the height)
MAX_TABLE_DEPTH_M = 3.0  # a table seen farther than this is not a useful hint
MAX_AUTO_DISPARITY = 256
DISPARITY_MARGIN_PX = 2  # extra labels beyond the computed window (rounding, pose error)


@dataclass(frozen=True)
class DisparityWindow:
    """The depth range ``[near, far]`` (m) the matcher covers with disparities
    0..max_disparity, and where the numbers came from (``source``, for logs and the CLI)."""

    near: float
    far: float
    max_disparity: int
    source: str


def table_depths(geometry: StereoGeometry, intrinsics: Intrinsics,
                 T_base_camera: np.ndarray) -> np.ndarray | None:
    """Depths (m, along the rectified axis) where the image corners and centre see the plane
    z = 0 of ``base``, or None if any of those rays misses it in front of the camera."""
    w, h = intrinsics.width - 1.0, intrinsics.height - 1.0
    pix = np.array([[0, 0, 1], [w, 0, 1], [0, h, 1], [w, h, 1], [w / 2, h / 2, 1]])
    rays = (T_base_camera[:3, :3] @ np.linalg.solve(intrinsics.K, pix.T)).T
    origin = T_base_camera[:3, 3]
    with np.errstate(divide="ignore", invalid="ignore"):
        t = -origin[2] / rays[:, 2]
    if origin[2] <= 0 or not np.all(np.isfinite(t) & (t > 0)):
        return None
    z = (rays * t[:, None]) @ geometry.R_rect[2]
    return None if np.any(z <= 0) or z.max() > MAX_TABLE_DEPTH_M else z


def choose_window(geometry: StereoGeometry, intrinsics: Intrinsics, T_base_camera: np.ndarray,
                  *, near: float | None = None, far: float | None = None,
                  max_disparity: int | str = "auto") -> DisparityWindow:
    """Choose ``[near, far]`` and the matcher's disparity budget (see module docstring).

    ``geometry`` is the rectified geometry before the disparity shift (only fx and the baseline
    are used); ``intrinsics``/``T_base_camera`` are the original left camera's.
    """
    check_range(near, far)
    fb = geometry.fx * geometry.baseline
    table = table_depths(geometry, intrinsics, T_base_camera)
    source = []
    if far is None:
        far = TABLE_FAR_MARGIN * float(table.max()) if table is not None else DEFAULT_FAR_M
        source.append("far from the table plane" if table is not None else "default far")
    if near is None:
        near = TABLE_NEAR_SHARE * float(table.min()) if table is not None else DEFAULT_NEAR_M
        near = min(near, far / 2.0)
        source.append("near from the table plane" if table is not None else "default near")
    check_range(near, far)
    needed = fb * (1.0 / near - 1.0 / far)
    limit = min(MAX_AUTO_DISPARITY, geometry.size[0] - 1)
    if max_disparity == "auto":
        n = min(int(math.ceil(needed)) + DISPARITY_MARGIN_PX, limit)
        if n < needed:
            log.warning("depth range %.3f-%.3f m needs %.0f disparities; capped at %d", near,
                        far, needed, n)
        source.append("auto budget")
    else:
        n = int(max_disparity)
        if not 1 <= n <= geometry.size[0] - 1:
            raise ConfigError(f"--max-disparity {n} must be in 1..{geometry.size[0] - 1} "
                              "(the rectified image width - 1)")
        if n < needed:
            log.warning("--max-disparity %d covers depths from %.3f m, not %.3f m", n,
                        fb / (fb / far + n), near)
        source.append("given budget")
    near = fb / (fb / far + n)  # what the budget actually covers
    return DisparityWindow(near=near, far=far, max_disparity=n, source=", ".join(source))


def fit_to_canvas(window: DisparityWindow, geometry: StereoGeometry, *,
                  auto: bool) -> DisparityWindow:
    """The matcher needs ``max_disparity < width`` of the final (cropped) rectified canvas."""
    limit = geometry.size[0] - 1
    if window.max_disparity <= limit:
        return window
    if not auto:
        raise ConfigError(f"--max-disparity {window.max_disparity} must be less than the "
                          f"rectified image width {geometry.size[0]}")
    fb = geometry.fx * geometry.baseline
    log.warning("disparity budget cut from %d to %d by the rectified width",
                window.max_disparity, limit)
    return replace(window, max_disparity=limit, near=fb / (fb / window.far + limit))


def check_range(near: float | None, far: float | None) -> None:
    """ConfigError unless ``near``/``far`` (m, either may be None) are positive, finite and
    ordered."""
    for name, v in (("near", near), ("far", far)):
        if v is not None and not (math.isfinite(v) and v > 0):
            raise ConfigError(f"--{name} must be a positive distance in metres, got {v}")
    if near is not None and far is not None and near >= far:
        raise ConfigError(f"--near {near} must be less than --far {far}")
