"""Baseline planning from depth accuracy (the rover thesis' stereo-configuration method).

For a rectified pair with focal length ``f`` (pixels) and baseline ``b`` (metres), a point at
depth ``Z`` has disparity ``d = f b / Z`` and a disparity error ``dd`` becomes a depth error

    dZ = Z^2 dd / (f b).

The baseline must be long enough for the wanted accuracy at the far end, short enough that the
disparity range ``f b (1/near - 1/far)`` fits the matcher's budget, and short enough that the two
views still overlap enough at the near end (overlap = 1 - f b / (near * image_extent)).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

from armstereo.errors import ConfigError


@dataclass(frozen=True)
class BaselineRecommendation:
    """A recommended baseline and what it gives. Lengths in metres, disparities in pixels."""

    baseline_m: float
    min_baseline_m: float  # shortest baseline meeting the accuracy at ``far``
    max_baseline_m: float  # longest allowed by the disparity budget and the overlap
    limited_by: str  # which constraint sets max_baseline_m: "disparity budget" or "overlap"
    near_m: float
    far_m: float
    focal_px: float
    disparity_near_px: float
    disparity_far_px: float
    disparity_range_px: float
    accuracy_near_m: float
    accuracy_far_m: float
    overlap_near: float
    overlap_far: float
    disparity_precision_px: float

    def as_dict(self) -> dict:
        return asdict(self)


def depth_error(z: float, focal_px: float, baseline_m: float, disparity_error_px: float) -> float:
    """Depth error (m) at depth ``z`` (m): Z^2 dd / (f b)."""
    return z * z * disparity_error_px / (focal_px * baseline_m)


def overlap(z: float, focal_px: float, baseline_m: float, extent_px: int) -> float:
    """Share of one view's width (along the baseline) that the other view also sees at depth z."""
    return max(0.0, 1.0 - focal_px * baseline_m / (z * extent_px))


def recommend_baseline(near: float, far: float, depth_accuracy: float, *, focal_px: float,
                  extent_px: int, max_disparity: int = 64, disparity_precision: float = 0.25,
                  min_overlap: float = 0.6) -> BaselineRecommendation:
    """Recommend the shortest baseline that reaches ``depth_accuracy`` (m) at ``far``.

    The shortest admissible baseline is chosen because it maximises overlap and keeps the two
    views most alike (matching is most reliable), while the accuracy target is still met.
    Raises ConfigError when no baseline satisfies all three constraints, naming the conflict.
    """
    _check_inputs(near, far, depth_accuracy, focal_px, max_disparity, disparity_precision,
                  min_overlap)
    b_min = far * far * disparity_precision / (focal_px * depth_accuracy)
    b_budget = max_disparity / (focal_px * (1.0 / near - 1.0 / far))
    b_overlap = (1.0 - min_overlap) * near * extent_px / focal_px
    b_max, limited_by = min((b_budget, "disparity budget"), (b_overlap, "overlap"))
    if b_min > b_max:
        raise ConfigError(
            f"no baseline reaches {depth_accuracy * 1000:.2f} mm at {far:.2f} m: accuracy needs "
            f">= {b_min:.3f} m but the {limited_by} allows <= {b_max:.3f} m; relax "
            "--depth-accuracy, narrow --near/--far or raise --max-disparity")
    b = min(math.ceil(b_min * 1000.0) / 1000.0, b_max)  # round up to whole millimetres
    return BaselineRecommendation(
        baseline_m=b, min_baseline_m=b_min, max_baseline_m=b_max, limited_by=limited_by,
        near_m=near, far_m=far, focal_px=focal_px,
        disparity_near_px=focal_px * b / near, disparity_far_px=focal_px * b / far,
        disparity_range_px=focal_px * b * (1.0 / near - 1.0 / far),
        accuracy_near_m=depth_error(near, focal_px, b, disparity_precision),
        accuracy_far_m=depth_error(far, focal_px, b, disparity_precision),
        overlap_near=overlap(near, focal_px, b, extent_px),
        overlap_far=overlap(far, focal_px, b, extent_px),
        disparity_precision_px=disparity_precision,
    )


def _check_inputs(near: float, far: float, accuracy: float, focal_px: float, max_disp: int,
                  precision: float, min_overlap: float) -> None:
    if not (0 < near < far):
        raise ConfigError(f"need 0 < --near < --far, got near={near} far={far}")
    if not 0 < accuracy < far:
        raise ConfigError(f"--depth-accuracy must be positive and less than --far ({far} m), "
                          f"got {accuracy}")
    if focal_px <= 0:
        raise ConfigError(f"focal length must be positive, got {focal_px}")
    if max_disp < 1:
        raise ConfigError(f"--max-disparity must be at least 1, got {max_disp}")
    if precision <= 0:
        raise ConfigError(f"--disparity-precision must be positive, got {precision}")
    if not (0 <= min_overlap < 1):
        raise ConfigError(f"--min-overlap must be in [0, 1), got {min_overlap}")
