"""Rigid transforms as 4x4 float64 arrays.

Naming: ``T_a_b`` maps points in frame b to frame a (the pose of b in a). UR's 6-vector poses
``[x, y, z, rx, ry, rz]`` (metres, axis-angle rotation vector) are converted only here and in
the UR driver.
"""

from __future__ import annotations

import logging

import numpy as np

from armstereo.errors import ArmstereoError, ConfigError

# One rule for every pose in the library: a rotation may be this far from orthonormal
# (max |R^T R - I|), which float64 arithmetic on valid rotations never exceeds.
ROTATION_TOLERANCE = 1e-6
# Poses typed by hand or printed by other tools (six decimals) are this far off at most; input
# edges (mount files, the public API) snap such rotations onto SO(3) instead of refusing them.
SNAP_TOLERANCE = 1e-3

log = logging.getLogger(__name__)


def make_T(R: np.ndarray, t: np.ndarray) -> np.ndarray:
    """4x4 transform from a 3x3 rotation and a 3-vector translation (metres)."""
    T = np.eye(4)
    T[:3, :3] = np.asarray(R, dtype=float)
    T[:3, 3] = np.asarray(t, dtype=float).reshape(3)
    return T


def invert(T: np.ndarray) -> np.ndarray:
    """Inverse of a rigid 4x4 transform (T_b_a from T_a_b)."""
    R = T[:3, :3]
    return make_T(R.T, -R.T @ T[:3, 3])


def transform_points(T_a_b: np.ndarray, p_b: np.ndarray) -> np.ndarray:
    """Map Nx3 points from frame b to frame a."""
    p_b = np.asarray(p_b, dtype=float)
    return p_b @ T_a_b[:3, :3].T + T_a_b[:3, 3]


def nearest_rotation(R: np.ndarray) -> np.ndarray:
    """The rotation matrix closest to ``R`` (3x3) in the Frobenius norm (SVD, det +1)."""
    U, _, Vt = np.linalg.svd(np.asarray(R, dtype=float))
    D = np.diag([1.0, 1.0, np.sign(np.linalg.det(U @ Vt))])
    return U @ D @ Vt


def rotation_error(R: np.ndarray) -> float:
    """How far ``R`` (3x3) is from orthonormal: max |R^T R - I|."""
    R = np.asarray(R, dtype=float)
    return float(np.abs(R.T @ R - np.eye(3)).max())


def as_rigid(T, name: str = "transform", *, error: type[ArmstereoError] = ConfigError,
             snap: bool = False) -> np.ndarray:
    """``T`` as a float64 4x4 rigid transform (a copy), or ``error`` naming ``name``.

    Checks: shape 4x4, finite, last row ``0 0 0 1``, rotation orthonormal within
    :data:`ROTATION_TOLERANCE` with determinant +1. With ``snap=True`` (input edges only) a
    rotation within :data:`SNAP_TOLERANCE` is replaced by the nearest rotation instead.
    """
    try:
        T = np.array(T, dtype=float)
    except (TypeError, ValueError):
        raise error(f"{name} must be a 4x4 array of numbers, got {T!r}") from None
    if T.shape != (4, 4):
        raise error(f"{name} must be a 4x4 transform, got shape {T.shape}")
    if not np.all(np.isfinite(T)):
        raise error(f"{name} is not a rigid transform: it holds NaN or inf")
    if np.abs(T[3] - (0.0, 0.0, 0.0, 1.0)).max() > ROTATION_TOLERANCE:
        raise error(f"{name} is not a rigid transform: its last row is {T[3].tolist()}, "
                    "not 0 0 0 1")
    R = T[:3, :3]
    err = rotation_error(R)
    limit = SNAP_TOLERANCE if snap else ROTATION_TOLERANCE
    if err > limit or np.linalg.det(R) <= 0:
        what = "a reflection" if np.linalg.det(R) <= 0 else f"|R^T R - I| = {err:.1e}"
        raise error(f"{name} is not a rigid transform: its rotation is {what} "
                    f"(tolerance {limit:.0e})")
    if err > ROTATION_TOLERANCE:
        log.info("%s: rotation re-orthonormalized (|R^T R - I| was %.1e)", name, err)
        T[:3, :3] = nearest_rotation(R)
    T[3] = (0.0, 0.0, 0.0, 1.0)
    return T


def rotvec_to_matrix(rotvec: np.ndarray) -> np.ndarray:
    """Rodrigues: axis-angle rotation vector (radians) to a 3x3 rotation matrix."""
    r = np.asarray(rotvec, dtype=float).reshape(3)
    theta = float(np.linalg.norm(r))
    if theta < 1e-12:
        return np.eye(3)
    k = r / theta
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + np.sin(theta) * K + (1 - np.cos(theta)) * (K @ K)


def matrix_to_rotvec(R: np.ndarray) -> np.ndarray:
    """3x3 rotation matrix to an axis-angle rotation vector; stable near 0 and near pi."""
    R = np.asarray(R, dtype=float)
    cos_theta = np.clip((np.trace(R) - 1.0) / 2.0, -1.0, 1.0)
    theta = float(np.arccos(cos_theta))
    if theta < 1e-9:
        return np.zeros(3)
    if np.pi - theta < 1e-6:
        # Near pi the antisymmetric part vanishes; take the axis from the symmetric part.
        B = (R + np.eye(3)) / 2.0
        i = int(np.argmax(np.diag(B)))
        axis = B[:, i] / np.sqrt(B[i, i])
        return axis * theta
    w = np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
    return w * (theta / (2.0 * np.sin(theta)))


def T_from_ur_pose(pose: np.ndarray) -> np.ndarray:
    """UR pose ``[x, y, z, rx, ry, rz]`` (metres, rotation vector) to a 4x4 transform."""
    pose = np.asarray(pose, dtype=float).reshape(6)
    return make_T(rotvec_to_matrix(pose[3:]), pose[:3])


def ur_pose_from_T(T: np.ndarray) -> np.ndarray:
    """4x4 transform to a UR pose ``[x, y, z, rx, ry, rz]``."""
    return np.concatenate([T[:3, 3], matrix_to_rotvec(T[:3, :3])])


def quaternion_xyzw(R: np.ndarray) -> np.ndarray:
    """3x3 rotation to a unit quaternion (x, y, z, w), w >= 0 (Foxglove's order)."""
    R = np.asarray(R, dtype=float)
    tr = np.trace(R)
    if tr > 0:
        s = 2.0 * np.sqrt(tr + 1.0)
        q = [(R[2, 1] - R[1, 2]) / s, (R[0, 2] - R[2, 0]) / s, (R[1, 0] - R[0, 1]) / s, s / 4]
    elif R[0, 0] > R[1, 1] and R[0, 0] > R[2, 2]:
        s = 2.0 * np.sqrt(1.0 + R[0, 0] - R[1, 1] - R[2, 2])
        q = [s / 4, (R[0, 1] + R[1, 0]) / s, (R[0, 2] + R[2, 0]) / s, (R[2, 1] - R[1, 2]) / s]
    elif R[1, 1] > R[2, 2]:
        s = 2.0 * np.sqrt(1.0 + R[1, 1] - R[0, 0] - R[2, 2])
        q = [(R[0, 1] + R[1, 0]) / s, s / 4, (R[1, 2] + R[2, 1]) / s, (R[0, 2] - R[2, 0]) / s]
    else:
        s = 2.0 * np.sqrt(1.0 + R[2, 2] - R[0, 0] - R[1, 1])
        q = [(R[0, 2] + R[2, 0]) / s, (R[1, 2] + R[2, 1]) / s, s / 4, (R[1, 0] - R[0, 1]) / s]
    q = np.asarray(q)
    q /= np.linalg.norm(q)
    return -q if q[3] < 0 else q


def matrix_from_quaternion_xyzw(q: np.ndarray) -> np.ndarray:
    """Unit quaternion (x, y, z, w) to a 3x3 rotation matrix."""
    x, y, z, w = np.asarray(q, dtype=float) / np.linalg.norm(q)
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


def rot_x(a: float) -> np.ndarray:
    """Rotation by ``a`` radians about x."""
    c, s = np.cos(a), np.sin(a)
    return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])


def rot_y(a: float) -> np.ndarray:
    """Rotation by ``a`` radians about y."""
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])


def rot_z(a: float) -> np.ndarray:
    """Rotation by ``a`` radians about z."""
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


def skew_stack(v: np.ndarray) -> np.ndarray:
    """(K, 3, 3) stack of the cross-product matrices [v]x of vectors v (K, 3):
    ``skew_stack(v)[k] @ w == np.cross(v[k], w)``."""
    v = np.asarray(v, dtype=np.float64)
    out = np.zeros((len(v), 3, 3))
    out[:, 0, 1], out[:, 0, 2] = -v[:, 2], v[:, 1]
    out[:, 1, 0], out[:, 1, 2] = v[:, 2], -v[:, 0]
    out[:, 2, 0], out[:, 2, 1] = -v[:, 1], v[:, 0]
    return out
