"""How well a fundamental matrix explains correspondences, in pixels.

Three measures, each per correspondence (``(N,)`` float64 pixels), for ``x2^T F x1 = 0``:

* :func:`sampson_distance`: the first-order approximation of the smallest total displacement
  of the two points that puts them on each other's epipolar lines, ``|x2^T F x1| /
  sqrt((F x1)_1^2 + (F x1)_2^2 + (F^T x2)_1^2 + (F^T x2)_2^2)``. This is the square root of what
  Hartley & Zisserman call the Sampson error, so it is in pixels.
* :func:`symmetric_epipolar_distance`: the mean of the two point-to-epipolar-line distances,
  ``(d(x2, F x1) + d(x1, F^T x2)) / 2``.
* :func:`reprojection_error`: each pair is triangulated optimally for F (Hartley-Sturm, through
  ``cv2.correctMatches``) and reprojected; the value is the RMS over the two images of the
  distance between observed and reprojected point. For small errors it is the Sampson distance
  divided by sqrt(2).
"""

from __future__ import annotations

import cv2
import numpy as np

from armstereo.epipolar.errors import EpipolarError
from armstereo.epipolar.projective import as_pairs, homogeneous

_TINY = 1e-300  # guards 0/0 for a point sitting on both epipoles


def _check_F(F: np.ndarray) -> np.ndarray:
    F = np.asarray(F, dtype=float)
    if F.shape != (3, 3) or not np.all(np.isfinite(F)):
        raise EpipolarError(f"F must be a finite 3x3 matrix, got shape {F.shape}")
    return F


def sampson_distance(F: np.ndarray, x1: np.ndarray, x2: np.ndarray) -> np.ndarray:
    """Sampson distance (px) of each correspondence ``x1[i] <-> x2[i]`` ((N, 2) px) under F."""
    F = _check_F(F)
    x1, x2 = as_pairs(x1, x2)
    return sampson_homogeneous(F, homogeneous(x1), homogeneous(x2))


def sampson_homogeneous(F: np.ndarray, h1: np.ndarray, h2: np.ndarray) -> np.ndarray:
    """:func:`sampson_distance` on unchecked ``(N, 3)`` homogeneous points with w = 1 (fast path
    for sampling loops)."""
    Fx1 = h1 @ F.T
    Ftx2 = h2 @ F
    num = np.abs(np.sum(h2 * Fx1, axis=1))
    den = np.sqrt(Fx1[:, 0] ** 2 + Fx1[:, 1] ** 2 + Ftx2[:, 0] ** 2 + Ftx2[:, 1] ** 2)
    return num / np.maximum(den, _TINY)


def symmetric_epipolar_distance(F: np.ndarray, x1: np.ndarray, x2: np.ndarray) -> np.ndarray:
    """Mean of the distances (px) of x2 to its epipolar line ``F x1`` and x1 to ``F^T x2``."""
    F = _check_F(F)
    x1, x2 = as_pairs(x1, x2)
    h1, h2 = homogeneous(x1), homogeneous(x2)
    Fx1 = h1 @ F.T
    Ftx2 = h2 @ F
    num = np.abs(np.sum(h2 * Fx1, axis=1))
    d2 = num / np.maximum(np.hypot(Fx1[:, 0], Fx1[:, 1]), _TINY)
    d1 = num / np.maximum(np.hypot(Ftx2[:, 0], Ftx2[:, 1]), _TINY)
    return (d1 + d2) / 2.0


def optimal_correction(F: np.ndarray, x1: np.ndarray,
                       x2: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The points closest to ``x1, x2`` (least squares, px) that satisfy ``x2^T F x1 = 0``.

    Hartley-Sturm optimal triangulation as implemented by ``cv2.correctMatches``; the
    triangulated 3D point of a corrected pair reprojects exactly onto it.
    """
    F = _check_F(F)
    x1, x2 = as_pairs(x1, x2)
    if len(x1) == 0:
        return x1.copy(), x2.copy()
    c1, c2 = cv2.correctMatches(F, x1[None], x2[None])
    return c1.reshape(-1, 2).astype(float), c2.reshape(-1, 2).astype(float)


def reprojection_error(F: np.ndarray, x1: np.ndarray, x2: np.ndarray) -> np.ndarray:
    """RMS over both images (px) of observed minus reprojected point, after optimal triangulation.
    """
    x1, x2 = as_pairs(x1, x2)
    c1, c2 = optimal_correction(F, x1, x2)
    d1 = np.sum((x1 - c1) ** 2, axis=1)
    d2 = np.sum((x2 - c2) ** 2, axis=1)
    return np.sqrt((d1 + d2) / 2.0)
