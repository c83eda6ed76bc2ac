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
:func:`solve_pairs` takes (A, B) arrays (K, 4, 4) and weights (K,) and returns a 4x4 X; the
per-pair quantities (:class:`PairData`) can be computed once and passed in.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from armstereo.calibration.poses import rotvec
from armstereo.transforms import make_T, skew_stack


@dataclass(frozen=True)
class PairData:
    """What the solvers need of K motion pairs, computed once (the leave-one-out selection
    solves the same pairs many times over): rotations and translations of A and B, their
    rotation vectors (rad) and unit quaternions (w >= 0)."""

    Ra: np.ndarray  # (K, 3, 3)
    ta: np.ndarray  # (K, 3)
    Rb: np.ndarray
    tb: np.ndarray
    wa: np.ndarray  # (K, 3) rotation vectors
    wb: np.ndarray
    qa: np.ndarray  # (K, 4) quaternions (w, x, y, z)
    qb: np.ndarray

    @classmethod
    def of(cls, A: np.ndarray, B: np.ndarray) -> PairData:
        A, B = np.asarray(A, float).reshape(-1, 4, 4), np.asarray(B, float).reshape(-1, 4, 4)
        wa = np.array([rotvec(a[:3, :3]) for a in A]).reshape(-1, 3)
        wb = np.array([rotvec(b[:3, :3]) for b in B]).reshape(-1, 3)
        return cls(A[:, :3, :3], A[:, :3, 3], B[:, :3, :3], B[:, :3, 3], wa, wb,
                   _quaternions(wa), _quaternions(wb))

    def __len__(self) -> int:
        return len(self.ta)

    def subset(self, keep: np.ndarray) -> PairData:
        return PairData(*(getattr(self, f)[keep] for f in
                          ("Ra", "ta", "Rb", "tb", "wa", "wb", "qa", "qb")))


def solve_pairs(method: str, A, B, w: np.ndarray, *, data: PairData | None = None
                ) -> np.ndarray:
    """X = T_flange_camera by ``method`` from motion pairs (A, B: (K, 4, 4)) weighted by
    ``w`` (>= 0); ``data`` (PairData of the same pairs) saves recomputing them.

    Raises ValueError for an unknown method or fewer than two pairs of positive weight, and
    np.linalg.LinAlgError when the pairs do not determine X.
    """
    w = np.asarray(w, float)
    keep = w > 0
    if int(keep.sum()) < 2:
        raise ValueError("a hand-eye solution needs at least two motion pairs")
    if method not in SOLVERS:
        raise ValueError(f"unknown hand-eye method {method!r}")
    d = data if data is not None else PairData.of(A, B)
    return SOLVERS[method](d.subset(keep), np.sqrt(w[keep]))


def _quaternions(w: np.ndarray) -> np.ndarray:
    th = np.linalg.norm(w, axis=1)
    axis = np.divide(w, th[:, None], out=np.zeros_like(w), where=th[:, None] > 1e-15)
    return np.concatenate([np.cos(th / 2)[:, None], np.sin(th / 2)[:, None] * axis], axis=1)


def _translation(d: PairData, R: np.ndarray, sw: np.ndarray) -> np.ndarray:
    """Least squares (R_A - I) t = R t_B - t_A, rows scaled by sqrt(w)."""
    M = (sw[:, None, None] * (d.Ra - np.eye(3))).reshape(-1, 3)
    rhs = (sw[:, None] * (d.tb @ R.T - d.ta)).reshape(-1)
    return np.linalg.lstsq(M, rhs, rcond=None)[0]


def _rotation_of_quaternion(q: np.ndarray) -> np.ndarray:
    w, x, y, z = np.asarray(q, float) / np.linalg.norm(q)
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def _tsai(d: PairData, sw) -> np.ndarray:
    # modified Rodrigues vectors P = 2 sin(theta/2) axis: skew(Pa + Pb) P' = Pb - Pa
    Pa, Pb = 2 * d.qa[:, 1:], 2 * d.qb[:, 1:]
    M = (sw[:, None, None] * skew_stack(Pa + Pb)).reshape(-1, 3)
    rhs = (sw[:, None] * (Pb - Pa)).reshape(-1)
    p_ = np.linalg.lstsq(M, rhs, rcond=None)[0]
    q = p_ / np.sqrt(1.0 + p_ @ p_)  # sin(theta/2) axis of X's rotation
    R = _rotation_of_quaternion(np.concatenate([[np.sqrt(max(0.0, 1.0 - q @ q))], q]))
    return make_T(R, _translation(d, R, sw))


def _park(d: PairData, sw) -> np.ndarray:
    # alpha = R beta for the rotation vectors; R = (M^T M)^(-1/2) M^T with M = sum beta alpha^T
    M = np.einsum("k,ki,kj->ij", sw * sw, d.wb, d.wa)
    lam, V = np.linalg.eigh(M.T @ M)
    if lam.min() <= 0:
        raise np.linalg.LinAlgError("the rotation axes do not span three dimensions")
    R = V @ np.diag(1.0 / np.sqrt(lam)) @ V.T @ M.T
    return make_T(R, _translation(d, R, sw))


def _left(q: np.ndarray) -> np.ndarray:
    """(K, 4, 4) matrices of q * p (quaternion product, p the unknown), q (K, 4)."""
    w, x, y, z = q.T
    return np.stack([np.stack([w, -x, -y, -z], -1), np.stack([x, w, -z, y], -1),
                     np.stack([y, z, w, -x], -1), np.stack([z, -y, x, w], -1)], 1)


def _right(q: np.ndarray) -> np.ndarray:
    """(K, 4, 4) matrices of p * q."""
    w, x, y, z = q.T
    return np.stack([np.stack([w, -x, -y, -z], -1), np.stack([x, w, z, -y], -1),
                     np.stack([y, -z, w, x], -1), np.stack([z, y, -x, w], -1)], 1)


def _horaud(d: PairData, sw) -> np.ndarray:
    # q_A * q_X = q_X * q_B: q_X is the null vector of sum (L(q_A) - R(q_B))^T (...)
    D = _left(d.qa) - _right(d.qb)
    S = np.einsum("k,kji,kjl->il", sw * sw, D, D)
    _, V = np.linalg.eigh(S)
    R = _rotation_of_quaternion(V[:, 0])
    return make_T(R, _translation(d, R, sw))


def _andreff(d: PairData, sw) -> np.ndarray:
    # vec(R) (row-major) and t from [I - kron(R_A, R_B), 0; kron(I, t_B^T), I - R_A] = [0; t_A]
    K = len(d)
    kron = np.einsum("kij,kab->kiajb", d.Ra, d.Rb).reshape(K, 9, 9)
    top = np.concatenate([np.eye(9) - kron, np.zeros((K, 9, 3))], axis=2)
    kt = np.einsum("ij,ka->kija", np.eye(3), d.tb).reshape(K, 3, 9)
    bottom = np.concatenate([kt, np.eye(3) - d.Ra], axis=2)
    rows = sw[:, None, None] * np.concatenate([top, bottom], axis=1)
    rhs = sw[:, None] * np.concatenate([np.zeros((K, 9)), d.ta], axis=1)
    x = np.linalg.lstsq(rows.reshape(-1, 12), rhs.reshape(-1), rcond=None)[0]
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


def _daniilidis(d: PairData, sw) -> np.ndarray:
    # Each pair gives 6 linear equations in the 8 entries of X's dual quaternion (q, q'); the
    # solution lies in the span of the two smallest right singular vectors, fixed by |q| = 1
    # and q . q' = 0.
    K = len(d)

    def dual(q, t):  # q' = 0.5 (0, t) * q
        return 0.5 * np.einsum("kij,kj->ki", _left(np.concatenate([np.zeros((K, 1)), t], 1)), q)

    u, v = d.qa[:, 1:], d.qb[:, 1:]
    u_, v_ = dual(d.qa, d.ta)[:, 1:], dual(d.qb, d.tb)[:, 1:]
    T = np.zeros((K, 6, 8))
    T[:, :3, 0], T[:, :3, 1:4] = u - v, skew_stack(u + v)
    T[:, 3:, 0], T[:, 3:, 1:4] = u_ - v_, skew_stack(u_ + v_)
    T[:, 3:, 4], T[:, 3:, 5:8] = u - v, skew_stack(u + v)
    _, _, Vt = np.linalg.svd((sw[:, None, None] * T).reshape(-1, 8), full_matrices=False)
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
    t = 2 * (_left(q_[None])[0] @ conj)[1:]
    return make_T(R, t)


SOLVERS = {"tsai": _tsai, "park": _park, "horaud": _horaud, "andreff": _andreff,
           "daniilidis": _daniilidis}
