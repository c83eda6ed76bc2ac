"""Fundamental matrix from correspondences, or from two known camera poses.

``estimate_fundamental(x1, x2, method)`` returns ``(F, inlier_mask)`` for ``(N, 2)`` pixel
arrays, with ``x2^T F x1 = 0``, ``F`` rank 2 and of unit Frobenius norm. The methods:

============  ==================================================================================
``8point``    Hartley-normalised 8-point least squares on all points (no outlier rejection).
``ransac``    OpenCV's RANSAC (7-point samples, inlier count), then the normalised 8-point
              refit on the inliers (H&Z algorithm 11.4; OpenCV alone skips it).
``lmeds``     least median of squares (needs no threshold to find the matrix, breaks down at
              50 % outliers): OpenCV's and our own sampling loop as starts, each polished by
              the Gold Standard; the one with most inliers wins (lmeds.py).
``mlesac``    Torr & Zisserman's MLESAC: 7-point samples scored by the likelihood of a Gaussian
              inlier / uniform outlier mixture whose mixing weight is found by EM.
``mapsac``    Torr's MAPSAC in its usual form, a truncated-quadratic (MSAC) score.
``magsac``    OpenCV's USAC with MAGSAC++ scoring (marginalises over the noise scale).
``gold``      Gold Standard (H&Z algorithm 11.3): MAGSAC start, then Levenberg-Marquardt over
              the second camera and the 3D points, minimising the reprojection error.
============  ==================================================================================

Whatever the method, the returned mask marks the correspondences whose Sampson distance under
the returned F is below ``threshold`` (px), so masks mean the same for every method.

Degenerate input raises :class:`~armstereo.epipolar.errors.DegenerateError` instead of returning
an arbitrary matrix: fewer than :data:`MIN_CORRESPONDENCES` pairs, or inliers that one
homography explains (all points on a plane, or a camera that only rotated); see
:func:`check_not_degenerate`. ``allow_degenerate=True`` skips the homography test (the motion
study uses it to show what the estimators return in those cases).
"""

from __future__ import annotations

import cv2
import numpy as np

from armstereo.epipolar.errors import DegenerateError, EpipolarError
from armstereo.epipolar.linear import (
    MIN_CORRESPONDENCES,
    OPENCV_FLAGS,
    eight_point,
    opencv_fundamental,
    refit_on_inliers,
)
from armstereo.epipolar.metrics import sampson_distance
from armstereo.epipolar.projective import (
    apply,
    as_pairs,
    check_camera_matrix,
    check_pose,
    normalized,
    skew,
)
from armstereo.epipolar.sampling import consensus

__all__ = [
    "DEFAULT_CONFIDENCE", "DEFAULT_MAX_ITERS", "DEFAULT_THRESHOLD_PX", "METHODS",
    "MIN_CORRESPONDENCES", "ROBUST_METHODS", "check_not_degenerate", "eight_point",
    "estimate_fundamental", "fundamental_from_poses", "off_plane_count", "refit_on_inliers",
]

METHODS = ("8point", "ransac", "lmeds", "mlesac", "mapsac", "magsac", "gold")
ROBUST_METHODS = tuple(m for m in METHODS if m != "8point")
DEFAULT_THRESHOLD_PX = 1.0  # inlier threshold on the Sampson distance (about 2 sigma at 0.5 px)
DEFAULT_CONFIDENCE = 0.999
DEFAULT_MAX_ITERS = 5000
# Degeneracy test: inliers farther than this many thresholds from the best homography's
# prediction count as "off the plane"; F needs at least this many / this share of them.
HOMOGRAPHY_THRESHOLD_FACTOR = 2.0
MIN_OFF_PLANE_POINTS = 8
MIN_OFF_PLANE_SHARE = 0.05
# Enough samples to find a plane holding 40 % of the points (at 99.9 %); a plane holding fewer
# leaves well over MIN_OFF_PLANE_SHARE of the points off it anyway.
HOMOGRAPHY_MAX_ITERS = 300



def estimate_fundamental(x1: np.ndarray, x2: np.ndarray, method: str, *,
                         threshold: float = DEFAULT_THRESHOLD_PX,
                         confidence: float = DEFAULT_CONFIDENCE,
                         max_iters: int = DEFAULT_MAX_ITERS, seed: int = 0,
                         allow_degenerate: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """Fundamental matrix of ``(N, 2)`` pixel correspondences ``x1[i] <-> x2[i]``.

    Returns ``(F, inlier_mask)``: F (3x3, rank 2, unit norm, ``x2^T F x1 = 0``) and an ``(N,)``
    bool mask (Sampson distance below ``threshold`` px). ``seed`` fixes the sampling of the
    methods implemented here (``mlesac``, ``mapsac``, ``lmeds``' own loop, the ``gold``
    start); OpenCV's own sampling is deterministic. Raises EpipolarError for malformed input
    or an unknown method and DegenerateError when the points do not determine F (see the
    module doc).
    """
    x1, x2 = as_pairs(x1, x2)
    _check_options(method, threshold, confidence, max_iters)
    if len(x1) < MIN_CORRESPONDENCES:
        raise DegenerateError(f"a fundamental matrix needs at least {MIN_CORRESPONDENCES} "
                              f"correspondences, got {len(x1)}")
    if method == "8point":
        F = eight_point(x1, x2)
    elif method == "magsac":  # MAGSAC++ ends with its own weighted least-squares fit
        F = opencv_fundamental(x1, x2, method, threshold, confidence, max_iters)
    elif method == "lmeds":
        from armstereo.epipolar.lmeds import lmeds_fundamental

        F = lmeds_fundamental(x1, x2, threshold=threshold, confidence=confidence,
                              max_iters=max_iters, seed=seed)
    elif method in OPENCV_FLAGS:
        F = refit_on_inliers(opencv_fundamental(x1, x2, method, threshold, confidence, max_iters),
                             x1, x2, threshold)
    elif method in ("mlesac", "mapsac"):
        F = consensus(x1, x2, method, threshold=threshold, confidence=confidence,
                      max_iters=max_iters, seed=seed)
    else:
        F = _gold(x1, x2, threshold, confidence, max_iters)
    F = normalized(F)
    mask = sampson_distance(F, x1, x2) < threshold
    if not allow_degenerate:
        check_not_degenerate(x1[mask] if method != "8point" else x1,
                             x2[mask] if method != "8point" else x2, threshold)
    return F, mask


def _gold(x1: np.ndarray, x2: np.ndarray, threshold: float, confidence: float,
          max_iters: int) -> np.ndarray:
    """Gold Standard refinement of the MAGSAC++ estimate on its inliers."""
    from armstereo.epipolar.gold import gold_standard

    F0 = opencv_fundamental(x1, x2, "magsac", threshold, confidence, max_iters)
    start = sampson_distance(F0, x1, x2) < threshold
    if start.sum() < MIN_CORRESPONDENCES:
        raise DegenerateError(f"only {int(start.sum())} correspondences fit the robust start "
                              f"within {threshold:g} px; the Gold Standard needs "
                              f"{MIN_CORRESPONDENCES}")
    return gold_standard(F0, x1[start], x2[start])


def _check_options(method: str, threshold: float, confidence: float, max_iters: int) -> None:
    if method not in METHODS:
        raise EpipolarError(f"unknown fundamental-matrix method {method!r}; choose one of "
                            f"{', '.join(METHODS)}")
    if not (np.isfinite(threshold) and threshold > 0):
        raise EpipolarError(f"threshold must be > 0 px, got {threshold}")
    if not 0 < confidence < 1:
        raise EpipolarError(f"confidence must lie in (0, 1), got {confidence}")
    if int(max_iters) < 1:
        raise EpipolarError(f"max_iters must be >= 1, got {max_iters}")


def check_not_degenerate(x1: np.ndarray, x2: np.ndarray, threshold: float) -> None:
    """Raise DegenerateError when one homography explains the inlier correspondences.

    A homography ``x2 ~ H x1`` relates all matches when every point lies on one plane or the
    camera only rotated; F is then a one-parameter family and any estimate is arbitrary. The
    best homography is fitted robustly (RANSAC, symmetric transfer error below
    ``HOMOGRAPHY_THRESHOLD_FACTOR * threshold`` px); F is accepted when at least
    ``max(MIN_OFF_PLANE_POINTS, MIN_OFF_PLANE_SHARE * N)`` inliers lie off it.
    """
    x1, x2 = as_pairs(x1, x2)
    if len(x1) < MIN_CORRESPONDENCES:
        raise DegenerateError(f"only {len(x1)} correspondences fit the estimate; a fundamental "
                              f"matrix needs at least {MIN_CORRESPONDENCES}")
    off = off_plane_count(x1, x2, HOMOGRAPHY_THRESHOLD_FACTOR * threshold)
    need = max(MIN_OFF_PLANE_POINTS, int(np.ceil(MIN_OFF_PLANE_SHARE * len(x1))))
    if off < need:
        raise DegenerateError(f"one homography explains {len(x1) - off} of {len(x1)} inlier "
                              f"correspondences, leaving {off} off it (need {need}): the "
                              "epipolar geometry is undetermined (the points lie on one plane, "
                              "the camera only rotated, or there are too few matches)")


def off_plane_count(x1: np.ndarray, x2: np.ndarray, threshold: float) -> int:
    """How many pairs the best robust homography does NOT explain within ``threshold`` px."""
    H, _ = cv2.findHomography(x1, x2, cv2.RANSAC, float(threshold),
                              maxIters=HOMOGRAPHY_MAX_ITERS, confidence=0.999)
    if H is None or not np.all(np.isfinite(H)) or abs(np.linalg.det(H)) < 1e-12:
        return len(x1)  # no usable homography: nothing explains the points jointly
    err = _symmetric_transfer(H, x1, x2)
    return int(np.sum(~(err < threshold)))


def _symmetric_transfer(H: np.ndarray, x1: np.ndarray, x2: np.ndarray) -> np.ndarray:
    """Larger of the two transfer distances (px) of each pair under H and H^-1."""
    with np.errstate(divide="ignore", invalid="ignore"):
        d2 = np.linalg.norm(apply(H, x1) - x2, axis=1)
        d1 = np.linalg.norm(apply(np.linalg.inv(H), x2) - x1, axis=1)
    return np.fmax(d1, d2)


def fundamental_from_poses(K1: np.ndarray, K2: np.ndarray, T_base_cam1: np.ndarray,
                           T_base_cam2: np.ndarray) -> np.ndarray:
    """F of two calibrated views: ``x2^T F x1 = 0`` for pixels of camera 1 and camera 2.

    ``K1``, ``K2``: 3x3 camera matrices (pixels, distortion-free). ``T_base_cam1/2``: 4x4 poses of
    the OpenCV camera frames in any common frame (e.g. ``base``), metres. With
    ``X2 = R X1 + t`` (camera 1 to camera 2), ``F = K2^-T [t]_x R K1^-1``, unit Frobenius norm.
    Raises DegenerateError when both optical centres coincide (F is undefined), EpipolarError
    for malformed matrices.
    """
    K1, K2 = check_camera_matrix(K1, "K1"), check_camera_matrix(K2, "K2")
    T1, T2 = check_pose(T_base_cam1, "T_base_cam1"), check_pose(T_base_cam2, "T_base_cam2")
    T21 = np.linalg.solve(T2, T1)  # T_cam2_cam1
    R, t = T21[:3, :3], T21[:3, 3]
    scale = max(1.0, float(np.linalg.norm(T1[:3, 3])), float(np.linalg.norm(T2[:3, 3])))
    if np.linalg.norm(t) <= 1e-12 * scale:
        raise DegenerateError("both camera centres coincide (zero baseline): a camera that "
                              "only rotates has no epipolar geometry")
    E = skew(t) @ R
    return normalized(np.linalg.inv(K2).T @ E @ np.linalg.inv(K1))
