"""Score a depth map against ground truth (the mock camera's exact z-depth).

Scored pixels: ground truth valid in the left view AND visible in the right view (the 3D point
projects inside the right image and is not hidden there: its depth agrees with the right view's
ground truth). ``density`` is the share of scored pixels that got an estimate; errors are relative
depth errors |Z_est - Z_gt| / Z_gt over the scored pixels that got one.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from armstereo.camera_model import Intrinsics
from armstereo.errors import StereoError
from armstereo.transforms import invert, transform_points

OCCLUSION_TOLERANCE = 0.01  # relative depth difference that still counts as "the same surface"


@dataclass(frozen=True)
class DepthAccuracy:
    """Accuracy of a depth map on the scored pixels (see module docstring)."""

    median_abs_rel_depth_error: float
    within_1pct: float  # share of scored pixels whose estimate is within 1 % (missing = miss)
    density: float
    mean_abs_rel_depth_error: float
    p90_abs_rel_depth_error: float
    scored_pixels: int

    def as_dict(self) -> dict:
        return asdict(self)


def visible_mask(depth_left: np.ndarray, intr_left: Intrinsics, T_base_left: np.ndarray,
                 depth_right: np.ndarray, intr_right: Intrinsics,
                 T_base_right: np.ndarray) -> np.ndarray:
    """Left pixels with ground truth that the right camera also sees (not occluded, in view).

    Depths are z-depth in metres in each camera's frame (OpenCV convention); poses map camera
    to base. Images are treated as undistorted pinholes (the mock renders ground truth depth
    per pixel; distortion is ignored here, which only matters within a pixel of occlusions).
    """
    h, w = depth_left.shape
    v, u = np.mgrid[0:h, 0:w].astype(np.float64)
    z = depth_left.astype(np.float64)
    ok = np.isfinite(z) & (z > 0)
    x = (u - intr_left.cx) / intr_left.fx * z
    y = (v - intr_left.cy) / intr_left.fy * z
    p_left = np.stack([x, y, z], axis=-1)[ok]
    T_right_left = invert(T_base_right) @ T_base_left
    p_right = transform_points(T_right_left, p_left)
    zr = p_right[:, 2]
    ur = intr_right.fx * p_right[:, 0] / zr + intr_right.cx
    vr = intr_right.fy * p_right[:, 1] / zr + intr_right.cy
    hr, wr = depth_right.shape
    inside = (zr > 0) & (ur >= 0) & (ur <= wr - 1) & (vr >= 0) & (vr <= hr - 1)
    seen = np.zeros(zr.shape, dtype=bool)
    iu = np.clip(np.rint(ur[inside]).astype(int), 0, wr - 1)
    iv = np.clip(np.rint(vr[inside]).astype(int), 0, hr - 1)
    zr_gt = depth_right[iv, iu]
    seen[inside] = np.isfinite(zr_gt) & (np.abs(zr_gt - zr[inside]) <= OCCLUSION_TOLERANCE
                                         * zr[inside])
    out = np.zeros((h, w), dtype=bool)
    out[ok] = seen
    return out


def score_depth(depth_est: np.ndarray, depth_gt: np.ndarray, mask: np.ndarray) -> DepthAccuracy:
    """Accuracy of ``depth_est`` against ``depth_gt`` (same view, metres) on ``mask`` pixels."""
    if depth_est.shape != depth_gt.shape or mask.shape != depth_gt.shape:
        raise StereoError(f"depth maps and mask differ in size: {depth_est.shape}, "
                          f"{depth_gt.shape}, {mask.shape}")
    scored = mask & np.isfinite(depth_gt) & (depth_gt > 0)
    n = int(scored.sum())
    if n == 0:
        raise StereoError("no pixel has valid, non-occluded ground truth to score against")
    est = depth_est[scored].astype(np.float64)
    gt = depth_gt[scored].astype(np.float64)
    got = np.isfinite(est) & (est > 0)
    rel = np.abs(est[got] - gt[got]) / gt[got]
    if rel.size == 0:
        return DepthAccuracy(float("nan"), 0.0, 0.0, float("nan"), float("nan"), n)
    return DepthAccuracy(
        median_abs_rel_depth_error=float(np.median(rel)),
        within_1pct=float(np.count_nonzero(rel <= 0.01) / n),
        density=float(got.sum() / n),
        mean_abs_rel_depth_error=float(rel.mean()),
        p90_abs_rel_depth_error=float(np.percentile(rel, 90)),
        scored_pixels=n,
    )
