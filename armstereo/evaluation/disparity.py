"""Disparity error metrics against ground truth (Middlebury-style bad-pixel rates).

Disparities are float32 of the left image, NaN = no estimate (estimates) or unknown (ground
truth). The scored pixels are those with finite ground truth, inside ``mask`` if one is given,
and at ``x >= exclude_left`` (the left band where a matcher with that search range cannot
answer). A missing estimate on a scored pixel counts as bad.
"""

from __future__ import annotations

import numpy as np

from armstereo.errors import StereoError


def evaluate_disparity(disp: np.ndarray, gt: np.ndarray, mask: np.ndarray | None = None, *,
                       exclude_left: int = 0) -> dict[str, float]:
    """Error statistics of ``disp`` against ``gt`` on the scored pixels (see module doc).

    Returns a dict: ``bad1``/``bad2`` (share of scored pixels with |error| > 1 / > 2 px or no
    estimate), ``avg_error`` and ``median_error`` (px, over scored pixels with an estimate),
    ``invalid`` (share of scored pixels without an estimate) and ``pixels`` (how many were
    scored). Shares are fractions in [0, 1]; errors are NaN when nothing was matched.
    Raises StereoError on shape mismatch or a negative ``exclude_left``.
    """
    disp = np.asarray(disp, np.float64)
    gt = np.asarray(gt, np.float64)
    if disp.shape != gt.shape or disp.ndim != 2:
        raise StereoError(f"disparity shape {disp.shape} does not match ground truth {gt.shape}")
    if exclude_left < 0:
        raise StereoError(f"exclude_left must be >= 0, got {exclude_left}")
    scored = np.isfinite(gt)
    if mask is not None:
        mask = np.asarray(mask)
        if mask.shape != gt.shape:
            raise StereoError(f"mask shape {mask.shape} does not match ground truth {gt.shape}")
        scored &= mask.astype(bool)
    scored[:, :exclude_left] = False
    n = int(scored.sum())
    if n == 0:
        raise StereoError("no pixel to score: ground truth, mask and exclude_left leave none")
    est = disp[scored]
    err = np.abs(est - gt[scored])
    have = np.isfinite(est)
    errors = err[have]
    return {
        "bad1": float(np.mean(~(err <= 1.0))),
        "bad2": float(np.mean(~(err <= 2.0))),
        "avg_error": float(errors.mean()) if errors.size else float("nan"),
        "median_error": float(np.median(errors)) if errors.size else float("nan"),
        "invalid": float(np.mean(~have)),
        "pixels": n,
    }
