"""Small rigid-motion helpers for calibration: checks, a local pose chart, means, differences.

Poses are 4x4 float64 ``T_a_b`` (metres). The chart used by the refinement is
``exp6(xi) = make_T(Rodrigues(xi[:3]), xi[3:])`` applied on the right of a reference pose:
``T = T_ref @ exp6(xi)``, so ``xi`` is a rotation vector (rad) and a translation (m), both in
the reference pose's own frame.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import cv2
import numpy as np

from armstereo.errors import ConfigError
from armstereo.transforms import make_T

RIGID_TOLERANCE = 1e-6  # max |R R^T - I| accepted from callers


def as_rigid(T, what: str) -> np.ndarray:
    """A finite 4x4 rigid transform as float64 (rotation snapped onto SO(3)); ConfigError
    naming ``what`` otherwise."""
    T = np.array(T, dtype=float)
    if T.shape != (4, 4) or not np.all(np.isfinite(T)):
        raise ConfigError(f"{what} must be a finite 4x4 transform, got shape {T.shape}")
    R = T[:3, :3]
    if (np.abs(R @ R.T - np.eye(3)).max() > RIGID_TOLERANCE or np.linalg.det(R) < 0
            or not np.allclose(T[3], [0, 0, 0, 1])):
        raise ConfigError(f"{what} is not a rigid transform")
    U, _, Vt = np.linalg.svd(R)
    T[:3, :3] = U @ Vt
    return T


def rotvec(R: np.ndarray) -> np.ndarray:
    """Rotation vector (rad, (3,)) of a 3x3 rotation."""
    return cv2.Rodrigues(np.ascontiguousarray(R, dtype=float))[0].reshape(3)


def rotmat(w: np.ndarray) -> np.ndarray:
    """3x3 rotation of a rotation vector (rad)."""
    return cv2.Rodrigues(np.asarray(w, dtype=float).reshape(3, 1))[0]


def exp6(xi: np.ndarray) -> np.ndarray:
    """4x4 pose of a chart vector (rotation vector rad, translation m)."""
    xi = np.asarray(xi, dtype=float)
    return make_T(rotmat(xi[:3]), xi[3:6])


def log6(T: np.ndarray) -> np.ndarray:
    """Chart vector (rotation vector rad, translation m) of a 4x4 pose (inverse of exp6)."""
    return np.concatenate([rotvec(T[:3, :3]), T[:3, 3]])


def right_jacobian(w: np.ndarray) -> np.ndarray:
    """3x3 J with Rodrigues(w + dw) = Rodrigues(w) Rodrigues(J dw) to first order."""
    w = np.asarray(w, dtype=float)
    th = float(np.linalg.norm(w))
    W = skew(w)
    if th < 1e-8:
        return np.eye(3) - 0.5 * W
    return (np.eye(3) - (1 - math.cos(th)) / th**2 * W
            + (th - math.sin(th)) / th**3 * (W @ W))


def chart_jacobian(xi: np.ndarray) -> np.ndarray:
    """6x6 M with T_ref exp6(xi + dxi) = T_ref exp6(xi) exp6(M dxi) to first order."""
    M = np.zeros((6, 6))
    M[:3, :3] = right_jacobian(xi[:3])
    M[3:, 3:] = rotmat(xi[:3]).T
    return M


def skew(v: np.ndarray) -> np.ndarray:
    """[v]x: skew(v) @ p == cross(v, p)."""
    x, y, z = np.asarray(v, dtype=float).reshape(3)
    return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])


def rotation_angle_deg(R: np.ndarray) -> float:
    """Angle (deg) of a 3x3 rotation, in [0, 180]."""
    c = (float(np.trace(R)) - 1.0) / 2.0
    return math.degrees(math.acos(min(1.0, max(-1.0, c))))


def pose_difference(T_a: np.ndarray, T_b: np.ndarray) -> tuple[float, float]:
    """(translation distance m, rotation angle deg) between two poses of one frame."""
    dt = float(np.linalg.norm(T_a[:3, 3] - T_b[:3, 3]))
    return dt, rotation_angle_deg(T_a[:3, :3].T @ T_b[:3, :3])


def mean_pose(poses: Sequence[np.ndarray]) -> np.ndarray:
    """Chordal mean of rotations (SVD projection of the summed matrices) and mean translation."""
    Rs = np.array([T[:3, :3] for T in poses])
    U, _, Vt = np.linalg.svd(Rs.sum(axis=0))
    R = U @ np.diag([1.0, 1.0, np.linalg.det(U @ Vt)]) @ Vt
    return make_T(R, np.mean([T[:3, 3] for T in poses], axis=0))


def pose_spread(poses: Sequence[np.ndarray]) -> tuple[float, float]:
    """RMS distance (m) and RMS rotation angle (deg) of poses about their mean."""
    ref = mean_pose(poses)
    d = [pose_difference(ref, T) for T in poses]
    return (float(np.sqrt(np.mean([x[0] ** 2 for x in d]))),
            float(np.sqrt(np.mean([x[1] ** 2 for x in d]))))
