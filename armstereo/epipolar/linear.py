"""The linear core every estimator shares: the Hartley-normalised 8-point algorithm and the
refit of a robust estimate on its inliers (H&Z algorithms 11.1 and 11.4).

Below both :mod:`~armstereo.epipolar.fundamental` (which picks the method) and
:mod:`~armstereo.epipolar.sampling` (MLESAC/MAPSAC), so neither imports the other back.
Pixels in, ``x2^T F x1 = 0``, F rank 2 and of unit Frobenius norm.
"""

from __future__ import annotations

import cv2
import numpy as np

from armstereo.epipolar.errors import DegenerateError
from armstereo.epipolar.metrics import sampson_distance
from armstereo.epipolar.projective import (
    apply,
    as_pairs,
    enforce_rank2,
    hartley_normalization,
    normalized,
)

MIN_CORRESPONDENCES = 8
# OpenCV's robust estimators by our method names
OPENCV_FLAGS = {"ransac": cv2.FM_RANSAC, "lmeds": cv2.FM_LMEDS, "magsac": cv2.USAC_MAGSAC}
# The 8-point system must have a one-dimensional null space: its second smallest singular
# value (normalised coordinates) must exceed this share of the largest one.
MIN_SINGULAR_RATIO = 1e-9


def eight_point(x1: np.ndarray, x2: np.ndarray) -> np.ndarray:
    """Hartley-normalised 8-point algorithm on all ``(N, 2)`` pairs (N >= 8), rank 2 enforced.

    Raises DegenerateError when the linear system does not single out one matrix (fewer than 8
    independent equations, e.g. collinear or exactly planar-and-rotating configurations).
    """
    x1, x2 = as_pairs(x1, x2)
    if len(x1) < MIN_CORRESPONDENCES:
        raise DegenerateError(f"the 8-point algorithm needs at least {MIN_CORRESPONDENCES} "
                              f"correspondences, got {len(x1)}")
    T1, T2 = hartley_normalization(x1), hartley_normalization(x2)
    n1, n2 = apply(T1, x1), apply(T2, x2)
    A = np.column_stack([n2[:, :1] * n1, n2[:, :1], n2[:, 1:] * n1, n2[:, 1:], n1,
                         np.ones(len(n1))])
    _, s, Vt = np.linalg.svd(A, full_matrices=False)
    if len(s) < 9 or s[-2] <= MIN_SINGULAR_RATIO * s[0]:
        raise DegenerateError("the correspondences do not single out one fundamental matrix "
                              "(the 8-point system has more than one solution)")
    Fn = enforce_rank2(Vt[-1].reshape(3, 3))
    return normalized(T2.T @ Fn @ T1)


def refit_on_inliers(F: np.ndarray, x1: np.ndarray, x2: np.ndarray, threshold: float,
                     rounds: int = 3) -> np.ndarray:
    """Re-estimate F by the 8-point algorithm on its inliers (Sampson < ``threshold`` px).

    Repeated while the inlier set grows, at most ``rounds`` times. Raises DegenerateError when
    fewer than 8 correspondences support F.
    """
    mask = sampson_distance(F, x1, x2) < threshold
    for _ in range(rounds):
        if mask.sum() < MIN_CORRESPONDENCES:
            break
        F_new = eight_point(x1[mask], x2[mask])
        new_mask = sampson_distance(F_new, x1, x2) < threshold
        if new_mask.sum() < mask.sum():
            break
        F, done, mask = F_new, bool(np.array_equal(new_mask, mask)), new_mask
        if done:
            break
    if mask.sum() < MIN_CORRESPONDENCES:
        raise DegenerateError(f"only {int(mask.sum())} correspondences support the estimate "
                              f"within {threshold:g} px; need {MIN_CORRESPONDENCES}")
    return F


def opencv_fundamental(x1: np.ndarray, x2: np.ndarray, method: str, threshold: float,
                       confidence: float, max_iters: int) -> np.ndarray:
    """One of OpenCV's robust estimators; raises DegenerateError when it finds nothing."""
    F, _ = cv2.findFundamentalMat(x1.astype(np.float64), x2.astype(np.float64),
                                  OPENCV_FLAGS[method], float(threshold), float(confidence),
                                  int(max_iters))
    if F is None or F.shape != (3, 3) or not np.all(np.isfinite(F)):
        raise DegenerateError(f"OpenCV's {method} found no fundamental matrix for these "
                              f"{len(x1)} correspondences")
    return enforce_rank2(F)
