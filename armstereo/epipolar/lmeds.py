"""Least median of squares for the fundamental matrix, with a consensus-keeping polish.

OpenCV's LMedS picks the 7-point sample whose median Sampson error is smallest. Its matrix
is only as good as one minimal sample of noisy points, and an 8-point refit on its inliers
settles on whichever self-consistent inlier set it starts from: with 30 % outliers at 0.5 px
of noise, one trial in ten kept only 82 % of the true inliers within the 1 px threshold
(bench/results/lmeds.md), where the true matrix keeps 90-100 %.

Here two starts are polished and the one that explains the most correspondences wins:

1. Starts: OpenCV's LMedS (refitted on its inliers, as before), and our own LMedS loop
   (:func:`armstereo.epipolar.sampling.consensus` with the median cost: every new best sample
   is locally optimised by 8-point refits while the median falls).
2. Polish: from each start, the Gold Standard (reprojection-error minimisation, gold.py) on
   the correspondences within 1x and 2x the threshold, re-selecting its inliers until they
   stop changing. The wider capture lets a start that cut off part of the true inliers take
   them back.
3. Choice: the most correspondences within the threshold, then the smallest truncated
   squared error (MSAC's score), so LMedS still needs no threshold to *find* the geometry and
   the threshold only decides between polished answers.
"""

from __future__ import annotations

import numpy as np

from armstereo.epipolar.errors import DegenerateError, EpipolarError
from armstereo.epipolar.linear import opencv_fundamental, refit_on_inliers
from armstereo.epipolar.metrics import sampson_distance

CAPTURE_FACTORS = (1.0, 2.0)  # polish on the points within these many thresholds
POLISH_ROUNDS = 4
MIN_POINTS = 8


def lmeds_fundamental(x1: np.ndarray, x2: np.ndarray, *, threshold: float, confidence: float,
                      max_iters: int, seed: int = 0) -> np.ndarray:
    """F (3x3) of ``(N, 2)`` pixel pairs by polished LMedS (module docstring); raises
    DegenerateError when no start yields a matrix."""
    from armstereo.epipolar.sampling import consensus

    starts = []
    try:
        starts.append(refit_on_inliers(opencv_fundamental(x1, x2, "lmeds", threshold, confidence,
                                               max_iters), x1, x2, threshold))
    except DegenerateError:
        pass
    try:
        starts.append(consensus(x1, x2, "lmeds", threshold=threshold, confidence=confidence,
                                max_iters=max_iters, seed=seed))
    except DegenerateError:
        pass
    if not starts:
        raise DegenerateError(f"LMedS found no fundamental matrix for these {len(x1)} "
                              "correspondences")
    candidates = list(starts)
    for F in starts:
        for factor in CAPTURE_FACTORS:
            polished = _polish(F, x1, x2, threshold, factor)
            if polished is not None:
                candidates.append(polished)
    return max(candidates, key=lambda F: _support(F, x1, x2, threshold))


def _polish(F: np.ndarray, x1: np.ndarray, x2: np.ndarray, threshold: float,
            factor: float) -> np.ndarray | None:
    """Gold Standard on the points within ``factor`` thresholds of F, then on its own inliers
    until they stop changing; None when too few points support it."""
    from armstereo.epipolar.gold import gold_standard

    mask = sampson_distance(F, x1, x2) < factor * threshold
    for _ in range(POLISH_ROUNDS):
        if mask.sum() < MIN_POINTS:
            return None
        try:
            F = gold_standard(F, x1[mask], x2[mask])
        except (EpipolarError, np.linalg.LinAlgError):
            return None
        if not np.all(np.isfinite(F)):
            return None
        new = sampson_distance(F, x1, x2) < threshold
        if np.array_equal(new, mask):
            break
        mask = new
    return F


def _support(F: np.ndarray, x1: np.ndarray, x2: np.ndarray, threshold: float):
    r = sampson_distance(F, x1, x2)
    return int(np.count_nonzero(r < threshold)), -float(np.sum(np.minimum(r, threshold) ** 2))
