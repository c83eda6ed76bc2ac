"""The region of interest: found from where the views look, and checked against them.

Without ``--roi`` the box is where the views agree: the reconstructed points that at least
half of the pairs (and at least two) have inside their image, their 0.5 .. 99.5 percentile box
per axis, grown by a margin (the truncation band plus two voxels, so surfaces at the edge keep
their band). A scan planned around a target gives the target's neighbourhood; a stray point or
the far background (seen by one or two views) does not stretch the box.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from armstereo.errors import ConfigError
from armstereo.fusion.tsdf import DepthFrame, Roi, rotate

AGREEMENT_SHARE = 0.5  # a point counts when this share of the pairs frame it
PERCENTILES = (0.5, 99.5)
POINTS_PER_FRAME = 20_000  # enough to place a box; cheap to project into every view
ROI_PROBES_PER_AXIS = 9  # grid of probe points when checking that a view sees the ROI


def frame_points(frame: DepthFrame, limit: int = POINTS_PER_FRAME) -> np.ndarray:
    """Base-frame points (N <= limit, 3) of a frame's valid depth, evenly strided."""
    v, u = np.nonzero(np.isfinite(frame.depth) & (frame.depth > 0))
    step = max(1, math.ceil(len(v) / limit))
    v, u = v[::step], u[::step]
    z = frame.depth[v, u].astype(np.float64)
    K = frame.K
    cam = np.column_stack([(u - K[0, 2]) / K[0, 0] * z, (v - K[1, 2]) / K[1, 1] * z, z])
    T = frame.T_base_camera
    return rotate(T[:3, :3], cam) + T[:3, 3]


def in_image(frame: DepthFrame, points: np.ndarray) -> np.ndarray:
    """Boolean (N,): the points project inside the frame's image, in front of the camera."""
    u, v, z = frame.project(points)
    h, w = frame.depth.shape
    with np.errstate(invalid="ignore"):
        return (z > 0) & (u >= -0.5) & (u < w - 0.5) & (v >= -0.5) & (v < h - 0.5)


def auto_roi(frames: Sequence[DepthFrame], points: Sequence[np.ndarray], margin: float) -> Roi:
    """The box the views agree on (module docstring); ConfigError without any point."""
    pts = [p[:: max(1, math.ceil(len(p) / POINTS_PER_FRAME))] for p in points if len(p)]
    if not pts:
        raise ConfigError("no pair produced any 3D point: there is nothing to fuse "
                          "(check the recording with armstereo reconstruct)")
    cloud = np.concatenate(pts).astype(np.float64)
    seen_by = np.zeros(len(cloud), dtype=np.int32)
    for frame in frames:
        seen_by += in_image(frame, cloud)
    need = max(2, math.ceil(AGREEMENT_SHARE * len(frames)))
    agreed = cloud[seen_by >= min(need, len(frames))]
    if len(agreed) < 100:  # the views hardly overlap: take everything they saw
        agreed = cloud
    lo = np.percentile(agreed, PERCENTILES[0], axis=0) - margin
    hi = np.percentile(agreed, PERCENTILES[1], axis=0) + margin
    return Roi(tuple(lo), tuple(hi))


def check_roi_seen(roi: Roi, frames: Sequence[DepthFrame]) -> None:
    """ConfigError naming the box when no frame has any part of it in its image."""
    axes = [np.linspace(a, b, ROI_PROBES_PER_AXIS) for a, b in zip(roi.lo, roi.hi, strict=True)]
    probes = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    if any(in_image(f, probes).any() for f in frames):
        return
    raise ConfigError(f"the region of interest {roi} (xmin,xmax,ymin,ymax,zmin,zmax m, base "
                      f"frame) is outside every view of the {len(frames)} pair(s); check --roi")
