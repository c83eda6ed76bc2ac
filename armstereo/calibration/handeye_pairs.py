"""The five classic closed-form hand-eye solutions (AX = XB), over chosen motion pairs.

OpenCV's ``calibrateHandEye`` forms every pair of the views it is given, so a pair that says
nothing (a rotation of a degree or two: its axis is noise) or that misleads (near a half turn:
the axis and quaternion sign become ambiguous) can only be avoided by dropping whole views.
These solvers take the pairs themselves, each with a weight (0 leaves it out), so every good
view keeps its good pairs. With every pair and unit weights they are the same estimators as
OpenCV's (the tests compare them to ``cv2.calibrateHandEye`` to 1e-9):

- ``tsai``: Tsai & Lenz 1989, modified Rodrigues vectors, rotation then translation.
- ``park``: Park & Martin 1994, rotation from the log map (orthogonal Procrustes form).
- ``horaud``: Horaud & Dornaika 1995, unit quaternion as the smallest eigenvector.
- ``andreff``: Andreff et al. 1999, rotation and translation as one linear system.
- ``daniilidis``: Daniilidis 1999, dual quaternions, rotation and translation together.

Pair (i, j): flange motion ``A = T_base_flange[j]^-1 T_base_flange[i]``, camera motion
``B = T_camera_board[j] T_camera_board[i]^-1``, ``A X = X B`` with ``X = T_flange_camera``.
All functions take (A, B) arrays (K, 4, 4) and weights (K,); they return a 4x4 X.
"""

from __future__ import annotations

import numpy as np

from armstereo.calibration.poses import rotvec, skew
from armstereo.transforms import make_T


def solve_pairs(method: str, A: np.ndarray, B: np.ndarray, w: np.ndarray) -> np.ndarray:
    """X = T_flange_camera by ``method`` from motion pairs (A, B) weighted by ``w`` (>= 0).

    Raises ValueError for an unknown method or fewer than two pairs of positive weight, and
    np.linalg.LinAlgError when the pairs do not determine X.
    """
    A, B, w = np.asarray(A, float), np.asarray(B, float), np.asarray(w, float)
    keep = w > 0
    if int(keep.sum()) < 2:
        raise ValueError("a hand-eye solution needs at least two motion pairs")
    if method not in SOLVERS:
        raise ValueError(f"unknown hand-eye method {method!r}")
    return SOLVERS[method](A[keep], B[keep], np.sqrt(w[keep]))


def _translation(A, B, R, sw) -> np.ndarray:
    """Least squares (R_A - I) t = R t_B - t_A, rows scaled by sqrt(w)."""
    M = np.concatenate([s * (a[:3, :3] - np.eye(3)) for a, s in zip(A, sw, strict=True)])
    rhs = np.concatenate([s * (R @ b[:3, 3] - a[:3, 3])
                          for a, b, s in zip(A, B, sw, strict=True)])
    return np.linalg.lstsq(M, rhs, rcond=None)[0]


def _quaternion(R: np.ndarray) -> np.ndarray:
    """Unit quaternion (w, x, y, z) of a rotation, w >= 0 (the same branch OpenCV picks for
    any rotation short of a half turn)."""
    axis_angle = rotvec(R)
    th = float(np.linalg.norm(axis_angle))
    if th < 1e-15:
        return np.array([1.0, 0.0, 0.0, 0.0])
    return np.concatenate([[np.cos(th / 2)], np.sin(th / 2) * axis_angle / th])


def _rotation_of_quaternion(q: np.ndarray) -> np.ndarray:
    w, x, y, z = np.asarray(q, float) / np.linalg.norm(q)
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def _tsai(A, B, sw) -> np.ndarray:
    # modified Rodrigues vectors P = 2 sin(theta/2) axis: skew(Pa + Pb) P' = Pb - Pa
    Pa = [2 * _quaternion(a[:3, :3])[1:] for a in A]
    Pb = [2 * _quaternion(b[:3, :3])[1:] for b in B]
    M = np.concatenate([s * skew(pa + pb) for pa, pb, s in zip(Pa, Pb, sw, strict=True)])
    rhs = np.concatenate([s * (pb - pa) for pa, pb, s in zip(Pa, Pb, sw, strict=True)])
    p_ = np.linalg.lstsq(M, rhs, rcond=None)[0]
    q = p_ / np.sqrt(1.0 + p_ @ p_)  # sin(theta/2) axis of X's rotation
    R = _rotation_of_quaternion(np.concatenate([[np.sqrt(max(0.0, 1.0 - q @ q))], q]))
    return make_T(R, _translation(A, B, R, sw))


def _park(A, B, sw) -> np.ndarray:
    # alpha = R beta for the rotation vectors; R = (M^T M)^(-1/2) M^T with M = sum beta alpha^T
    M = sum(s * s * np.outer(rotvec(b[:3, :3]), rotvec(a[:3, :3]))
            for a, b, s in zip(A, B, sw, strict=True))
    lam, V = np.linalg.eigh(M.T @ M)
    if lam.min() <= 0:
        raise np.linalg.LinAlgError("the rotation axes do not span three dimensions")
    R = V @ np.diag(1.0 / np.sqrt(lam)) @ V.T @ M.T
    return make_T(R, _translation(A, B, R, sw))


def _left(q) -> np.ndarray:
    """4x4 matrix of q * p (quaternion product, p the unknown)."""
    w, x, y, z = q
    return np.array([[w, -x, -y, -z], [x, w, -z, y], [y, z, w, -x], [z, -y, x, w]])


def _right(q) -> np.ndarray:
    """4x4 matrix of p * q."""
    w, x, y, z = q
    return np.array([[w, -x, -y, -z], [x, w, z, -y], [y, -z, w, x], [z, y, -x, w]])


def _horaud(A, B, sw) -> np.ndarray:
    # q_A * q_X = q_X * q_B: q_X is the null vector of sum (L(q_A) - R(q_B))^T (...)
    S = np.zeros((4, 4))
    for a, b, s in zip(A, B, sw, strict=True):
        D = _left(_quaternion(a[:3, :3])) - _right(_quaternion(b[:3, :3]))
        S += s * s * D.T @ D
    _, V = np.linalg.eigh(S)
    R = _rotation_of_quaternion(V[:, 0])
    return make_T(R, _translation(A, B, R, sw))


def _andreff(A, B, sw) -> np.ndarray:
    # vec(R) (row-major) and t from [I - kron(R_A, R_B), 0; kron(I, t_B^T), I - R_A] = [0; t_A]
    rows, rhs = [], []
    for a, b, s in zip(A, B, sw, strict=True):
        Ra, Rb, ta, tb = a[:3, :3], b[:3, :3], a[:3, 3], b[:3, 3]
        top = np.hstack([np.eye(9) - np.kron(Ra, Rb), np.zeros((9, 3))])
        bottom = np.hstack([np.kron(np.eye(3), tb[None, :]), np.eye(3) - Ra])
        rows.append(s * np.vstack([top, bottom]))
        rhs.append(s * np.concatenate([np.zeros(9), ta]))
    x = np.linalg.lstsq(np.vstack(rows), np.concatenate(rhs), rcond=None)[0]
    return make_T(_nearest_rotation(x[:9].reshape(3, 3)), x[9:])


def _nearest_rotation(M: np.ndarray) -> np.ndarray:
    """The rotation nearest to a matrix that is a rotation up to scale and noise."""
    det = float(np.linalg.det(M))
    if abs(det) < np.finfo(np.float32).eps:
        raise np.linalg.LinAlgError("the linear hand-eye system gave a singular rotation")
    U, _, Vt = np.linalg.svd(M * np.cbrt(np.sign(det) / abs(det)))
    R = U @ Vt
    if np.linalg.det(R) < 0:
        R = U @ np.diag([1.0, 1.0, -1.0]) @ Vt
    return R


def _dual_quaternion(T: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    q = _quaternion(T[:3, :3])
    return q, 0.5 * _left(np.concatenate([[0.0], T[:3, 3]])) @ q


def _daniilidis(A, B, sw) -> np.ndarray:
    # Each pair gives 6 linear equations in the 8 entries of X's dual quaternion (q, q'); the
    # solution lies in the span of the two smallest right singular vectors, fixed by |q| = 1
    # and q . q' = 0.
    blocks = []
    for a, b, s in zip(A, B, sw, strict=True):
        (qa, qa_), (qb, qb_) = _dual_quaternion(a), _dual_quaternion(b)
        u, v, u_, v_ = qa[1:], qb[1:], qa_[1:], qb_[1:]
        T = np.zeros((6, 8))
        T[:3, 0], T[:3, 1:4] = u - v, skew(u + v)
        T[3:, 0], T[3:, 1:4] = u_ - v_, skew(u_ + v_)
        T[3:, 4], T[3:, 5:8] = u - v, skew(u + v)
        blocks.append(s * T)
    _, _, Vt = np.linalg.svd(np.vstack(blocks))
    v1, v2 = Vt[6], Vt[7]
    u1, w1, u2, w2 = v1[:4], v1[4:], v2[:4], v2[4:]
    a, b, c = u1 @ w1, u1 @ w2 + u2 @ w1, u2 @ w2
    disc = b * b - 4 * a * c
    if abs(a) < 1e-300 or disc < 0:
        raise np.linalg.LinAlgError("the dual-quaternion constraint has no real solution")
    roots = ((-b + np.sqrt(disc)) / (2 * a), (-b - np.sqrt(disc)) / (2 * a))
    norms = [r * r * (u1 @ u1) + 2 * r * (u1 @ u2) + u2 @ u2 for r in roots]
    k = int(np.argmax(norms))
    l2 = np.sqrt(1.0 / norms[k])
    dq = roots[k] * l2 * v1 + l2 * v2
    q, q_ = dq[:4], dq[4:]
    R = _rotation_of_quaternion(q)
    conj = q * np.array([1.0, -1.0, -1.0, -1.0])
    t = 2 * (_left(q_) @ conj)[1:]
    return make_T(R, t)


SOLVERS = {"tsai": _tsai, "park": _park, "horaud": _horaud, "andreff": _andreff,
           "daniilidis": _daniilidis}
