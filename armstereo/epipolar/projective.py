"""Small projective-geometry helpers shared by the estimators (pixels, homogeneous 3-vectors).

Conventions: point arrays are ``(N, 2)`` float64 pixel coordinates (OpenCV: pixel centres at
integers, x right, y down); a fundamental matrix ``F`` satisfies ``x2^T F x1 = 0`` for a point
``x1`` in image 1 and its match ``x2`` in image 2, and is returned with unit Frobenius norm.
"""

from __future__ import annotations

import numpy as np

from armstereo.epipolar.errors import EpipolarError

SQRT2 = float(np.sqrt(2.0))
POSE_TOLERANCE = 1e-6  # how far a pose's rotation may be from orthonormal


def as_points(x: np.ndarray, name: str) -> np.ndarray:
    """``x`` as a finite ``(N, 2)`` float64 array; raises EpipolarError otherwise."""
    x = np.asarray(x, dtype=float)
    if x.ndim != 2 or x.shape[1] != 2:
        raise EpipolarError(f"{name} must be an (N, 2) array of pixel coordinates, got shape "
                            f"{x.shape}")
    if not np.all(np.isfinite(x)):
        raise EpipolarError(f"{name} holds {int(np.sum(~np.isfinite(x)))} non-finite value(s)")
    return x


def as_pairs(x1: np.ndarray, x2: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two checked ``(N, 2)`` arrays of the same length."""
    x1, x2 = as_points(x1, "x1"), as_points(x2, "x2")
    if len(x1) != len(x2):
        raise EpipolarError(f"x1 has {len(x1)} points but x2 has {len(x2)}")
    return x1, x2


def homogeneous(x: np.ndarray) -> np.ndarray:
    """``(N, 2)`` -> ``(N, 3)`` with a trailing 1."""
    h = np.ones((len(x), 3))
    h[:, :2] = x
    return h


def skew(v: np.ndarray) -> np.ndarray:
    """3x3 matrix ``[v]_x`` with ``[v]_x w = v x w``."""
    x, y, z = np.asarray(v, dtype=float).reshape(3)
    return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])


def hartley_normalization(x: np.ndarray) -> np.ndarray:
    """3x3 similarity T moving the centroid to 0 and the mean distance to sqrt(2) (Hartley 1997).

    Coincident points (zero spread) raise EpipolarError: they carry no geometry.
    """
    centre = x.mean(axis=0)
    spread = float(np.mean(np.linalg.norm(x - centre, axis=1)))
    if not spread > 0:
        raise EpipolarError("all points coincide: no epipolar geometry can be computed")
    s = SQRT2 / spread
    return np.array([[s, 0.0, -s * centre[0]], [0.0, s, -s * centre[1]], [0.0, 0.0, 1.0]])


def apply(T: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Apply a 3x3 homography to ``(N, 2)`` points (no check of the sign of w)."""
    h = homogeneous(x) @ T.T
    return h[:, :2] / h[:, 2:]


def enforce_rank2(F: np.ndarray) -> np.ndarray:
    """Closest rank-2 matrix in the Frobenius norm (zero the smallest singular value)."""
    U, s, Vt = np.linalg.svd(F)
    return U @ np.diag([s[0], s[1], 0.0]) @ Vt


def normalized(F: np.ndarray) -> np.ndarray:
    """``F`` scaled to unit Frobenius norm with its largest-magnitude entry positive.

    The sign rule makes equal matrices compare equal (F and -F are the same geometry).
    """
    F = np.asarray(F, dtype=float)
    n = float(np.linalg.norm(F))
    if not n > 0 or not np.isfinite(n):
        raise EpipolarError("the fundamental matrix is zero or not finite")
    F = F / n
    k = int(np.argmax(np.abs(F)))
    return F if F.flat[k] > 0 else -F


def epipoles(F: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Homogeneous epipoles ``(e1, e2)`` with ``F e1 = 0`` and ``F^T e2 = 0`` (unit 3-vectors).

    ``e1`` is camera 2's centre seen in image 1, ``e2`` camera 1's centre seen in image 2.
    """
    U, _, Vt = np.linalg.svd(F)
    return Vt[-1], U[:, -1]


def cameras_from_fundamental(F: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Canonical projective cameras ``P1 = [I | 0]``, ``P2 = [[e2]_x F | e2]`` (H&Z 9.14)."""
    _, e2 = epipoles(F)
    P1 = np.hstack([np.eye(3), np.zeros((3, 1))])
    P2 = np.hstack([skew(e2) @ F, e2[:, None]])
    return P1, P2


def check_camera_matrix(K: np.ndarray, name: str) -> np.ndarray:
    """``K`` as a finite, invertible 3x3 float64 array; raises EpipolarError otherwise."""
    K = np.asarray(K, dtype=float)
    if K.shape != (3, 3) or not np.all(np.isfinite(K)) or abs(np.linalg.det(K)) < 1e-12:
        raise EpipolarError(f"{name} must be a finite, invertible 3x3 camera matrix")
    return K


def check_pose(T: np.ndarray, name: str) -> np.ndarray:
    """``T`` as a rigid 4x4 float64 transform (metres); raises EpipolarError otherwise."""
    T = np.asarray(T, dtype=float)
    if T.shape != (4, 4) or not np.all(np.isfinite(T)):
        raise EpipolarError(f"{name} must be a finite 4x4 pose, got shape {T.shape}")
    R = T[:3, :3]
    err = float(np.abs(R.T @ R - np.eye(3)).max())
    if err > POSE_TOLERANCE or np.linalg.det(R) <= 0 or np.any(T[3] != (0, 0, 0, 1)):
        raise EpipolarError(f"{name} is not a rigid transform (rotation off by {err:.2g})")
    return T
