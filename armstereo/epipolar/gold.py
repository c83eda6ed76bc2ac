"""Gold Standard fundamental matrix (Hartley & Zisserman, algorithm 11.3).

Starting from an estimate F0, Levenberg-Marquardt minimises the reprojection error
``sum |x1 - P1 X|^2 + |x2 - P2 X|^2`` over the second camera ``P2`` (12 numbers) and one point
per correspondence, with ``P1 = [I | 0]`` fixed, and returns ``F = [m]_x M`` for ``P2 = [M | m]``.
Coordinates are Hartley-normalised per image for conditioning.

Each point is parametrised as ``X = (u, v, 1, rho)``: ``(u, v)`` is its projection in image 1
and ``rho`` its projective depth, so points "at infinity" of the projective frame cause no
trouble. The normal equations are solved with the Schur complement on the 12 camera numbers
(H&Z A6.3), so a step costs O(N).
"""

from __future__ import annotations

import cv2
import numpy as np

from armstereo.epipolar.projective import (
    apply,
    cameras_from_fundamental,
    hartley_normalization,
    skew,
)

MAX_ITERATIONS = 100
INITIAL_DAMPING = 1e-3
MIN_RELATIVE_DECREASE = 1e-12
MAX_DAMPING = 1e12


def gold_standard(F0: np.ndarray, x1: np.ndarray, x2: np.ndarray) -> np.ndarray:
    """Refine F0 (3x3) on inlier pairs ``x1, x2`` ((N, 2) px, N >= 8); returns the refined F."""
    T1, T2 = hartley_normalization(x1), hartley_normalization(x2)
    n1, n2 = apply(T1, x1), apply(T2, x2)
    Fn = np.linalg.inv(T2).T @ F0 @ np.linalg.inv(T1)
    # unit norm: the canonical P2 = [[e']_x F | e'] mixes F's scale with the unit e'
    P2, points = _initial(Fn / np.linalg.norm(Fn), n1, n2)
    P2, points = _levenberg_marquardt(P2, points, n1, n2)
    M, m = P2[:, :3], P2[:, 3]
    return T2.T @ (skew(m) @ M) @ T1


def _initial(Fn: np.ndarray, n1: np.ndarray, n2: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Canonical P2 of Fn and each point's (u, v, rho) from optimal triangulation."""
    P1, P2 = cameras_from_fundamental(Fn)
    c1, c2 = cv2.correctMatches(Fn, n1[None], n2[None])
    c1, c2 = c1.reshape(-1, 2), c2.reshape(-1, 2)
    X = cv2.triangulatePoints(P1, P2, c1.T, c2.T).T  # (N, 4), homogeneous
    w = X[:, 2:3]
    w = np.where(np.abs(w) < 1e-12, 1e-12, w)
    X = X / w  # (u, v, 1, rho)
    return P2 / np.linalg.norm(P2), X[:, [0, 1, 3]]


def _residuals(P2: np.ndarray, pts: np.ndarray, n1: np.ndarray, n2: np.ndarray):
    """Residuals (obs - pred) in both images, and the homogeneous image-2 projections."""
    X = np.column_stack([pts[:, 0], pts[:, 1], np.ones(len(pts)), pts[:, 2]])
    y = X @ P2.T
    r1 = n1 - pts[:, :2]
    r2 = n2 - y[:, :2] / y[:, 2:]
    return r1, r2, X, y


def _cost(P2, pts, n1, n2) -> float:
    r1, r2, _, _ = _residuals(P2, pts, n1, n2)
    return float(np.sum(r1 ** 2) + np.sum(r2 ** 2))


def _jacobians(P2: np.ndarray, X: np.ndarray, y: np.ndarray):
    """d(image-2 projection)/d(P2) as (N, 2, 12) and d/d(u, v, rho) as (N, 2, 3)."""
    n = len(X)
    dpi = np.zeros((n, 2, 3))
    dpi[:, 0, 0] = dpi[:, 1, 1] = 1.0 / y[:, 2]
    dpi[:, 0, 2] = -y[:, 0] / y[:, 2] ** 2
    dpi[:, 1, 2] = -y[:, 1] / y[:, 2] ** 2
    dy_dP = np.zeros((n, 3, 12))
    for k in range(3):
        dy_dP[:, k, 4 * k:4 * k + 4] = X
    Ja = dpi @ dy_dP
    Jb = dpi @ P2[:, [0, 1, 3]][None]
    return Ja, Jb


def _step(P2, pts, n1, n2, lam: float):
    """One damped Gauss-Newton step via the Schur complement; returns the new (P2, pts)."""
    r1, r2, X, y = _residuals(P2, pts, n1, n2)
    Ja, Jb = _jacobians(P2, X, y)
    U = np.einsum("nki,nkj->ij", Ja, Ja)
    V = np.einsum("nki,nkj->nij", Jb, Jb)
    V[:, 0, 0] += 1.0  # image 1: d(u, v)/d(u, v) = I
    V[:, 1, 1] += 1.0
    W = np.einsum("nki,nkj->nij", Ja, Jb)
    ea = np.einsum("nki,nk->i", Ja, r2)
    eb = np.einsum("nki,nk->ni", Jb, r2)
    eb[:, :2] += r1
    U_aug = U + lam * np.diag(np.diag(U) + 1e-12)
    V_aug = V + lam * np.einsum("ij,nj->nij", np.eye(3), np.diagonal(V, axis1=1, axis2=2)
                                + 1e-12)
    V_inv = np.linalg.inv(V_aug)
    Y = W @ V_inv
    S = U_aug - np.einsum("nij,nkj->ik", Y, W)
    rhs = ea - np.einsum("nij,nj->i", Y, eb)
    da = np.linalg.lstsq(S, rhs, rcond=None)[0]
    db = np.einsum("nij,nj->ni", V_inv, eb - np.einsum("nji,j->ni", W, da))
    P2_new = P2 + da.reshape(3, 4)
    return P2_new / np.linalg.norm(P2_new), pts + db


def _levenberg_marquardt(P2, pts, n1, n2):
    cost = _cost(P2, pts, n1, n2)
    lam = INITIAL_DAMPING
    for _ in range(MAX_ITERATIONS):
        P2_new, pts_new = _step(P2, pts, n1, n2, lam)
        new_cost = _cost(P2_new, pts_new, n1, n2)
        if np.isfinite(new_cost) and new_cost < cost:
            done = cost - new_cost <= MIN_RELATIVE_DECREASE * cost
            P2, pts, cost = P2_new, pts_new, new_cost
            lam = max(lam / 10.0, 1e-12)
            if done:
                break
        else:
            lam *= 10.0
            if lam > MAX_DAMPING:
                break
    return P2, pts
