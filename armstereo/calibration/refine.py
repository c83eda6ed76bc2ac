"""Joint least-squares refinement of hand-eye, board pose, arm pose error (and intrinsics).

Model, per view i and corner j (frames: base = controller base, flange = tool0)::

    T_base_flange_true[i] = T_base_flange[i] @ exp6(delta[i])      # the arm's pose error
    uv[i, j] = project(K, dist, inv(X) @ inv(T_base_flange_true[i]) @ T_base_board @ P[j])

with X = T_flange_camera. Unknowns: X, T_base_board, delta[i] (6 per view) and optionally the
intrinsics. Residuals: the corners' pixel errors divided by ``pixel_sigma`` and the pose errors
divided by their prior sigmas (rotation, translation). A refinement that trusts forward
kinematics exactly (delta = 0) turns millimetre-level kinematic error straight into hand-eye
error; one with free deltas and a realistic prior lets the images overrule the arm where they
are more precise. The sigmas themselves are estimated from the data (variance component
estimation over a few rounds), so an ideal arm ends up trusted and a sloppy one is not. With
``pose_error=None`` the deltas are held at zero (the trusting model, kept for comparison).

The Jacobian is analytic: OpenCV's ``projectPoints`` gives d(uv)/d(camera point) and the
intrinsics' columns; poses are perturbed on the right through :mod:`poses`' chart.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, replace
from functools import partial

import cv2
import numpy as np
from scipy.optimize import least_squares

from armstereo.calibration.board import Detection
from armstereo.calibration.intrinsics import DISTORTION_MODELS
from armstereo.calibration.poses import chart_jacobian, exp6
from armstereo.camera_model import Intrinsics
from armstereo.transforms import invert

DEFAULT_PIXEL_SIGMA = 0.3  # px, starting value; estimated from the residuals
SIGMA_FLOOR_T = 1e-6  # m: pose-error sigmas never go below these (keeps the prior finite)
SIGMA_FLOOR_R = 1e-6  # rad
VARIANCE_ROUNDS = 4  # fits; the sigmas are re-estimated between them
_FTOL = 1e-12
MAX_EVALUATIONS = 400


@dataclass(frozen=True)
class PoseErrorPrior:
    """Standard deviations (per axis) of the arm's reported flange pose error, flange frame.

    ``estimate``: re-estimate both from the data (starting from these values).
    """

    translation_m: float = 0.0005
    rotation_rad: float = math.radians(0.03)
    estimate: bool = True


@dataclass(frozen=True)
class RefineResult:
    """Refined ``T_flange_camera``, ``T_base_board`` (base frame), intrinsics, per-view pose
    corrections ``delta`` (V, 6: rotation vector rad, translation m, flange frame), the sigmas
    used, pixel RMS (overall and per view) and the 6x6 covariance of X's chart (rotation
    vector, translation) from the final Jacobian."""

    T_flange_camera: np.ndarray
    T_base_board: np.ndarray
    intrinsics: Intrinsics
    delta: np.ndarray
    pixel_sigma: float
    pose_sigma_t: float
    pose_sigma_r: float
    rms_px: float
    per_view_rms_px: np.ndarray
    covariance_X: np.ndarray
    iterations: int


@dataclass
class _Problem:
    detections: list[Detection]
    F: list[np.ndarray]  # reported T_base_flange
    X0: np.ndarray
    B0: np.ndarray
    intr0: Intrinsics
    n_dist: int  # free distortion coefficients (leading ones)
    refine_intrinsics: bool
    with_delta: bool
    sigma_px: float
    sigma_t: float
    sigma_r: float

    @property
    def n_views(self) -> int:
        return len(self.F)

    @property
    def n_intr(self) -> int:
        return 4 + self.n_dist if self.refine_intrinsics else 0

    @property
    def n_params(self) -> int:
        return 12 + self.n_intr + (6 * self.n_views if self.with_delta else 0)

    def split(self, x: np.ndarray):
        xi_X, xi_B = x[:6], x[6:12]
        intr = x[12:12 + self.n_intr]
        delta = x[12 + self.n_intr:].reshape(-1, 6) if self.with_delta else \
            np.zeros((self.n_views, 6))
        return xi_X, xi_B, intr, delta

    def intrinsics(self, p: np.ndarray) -> Intrinsics:
        if not self.refine_intrinsics:
            return self.intr0
        K = np.array([[p[0], 0.0, p[2]], [0.0, p[1], p[3]], [0.0, 0.0, 1.0]])
        dist = self.intr0.dist.copy()
        dist[:self.n_dist] = p[4:]
        return Intrinsics(self.intr0.width, self.intr0.height, K, dist)

    def x0(self) -> np.ndarray:
        x = np.zeros(self.n_params)
        if self.refine_intrinsics:
            K = self.intr0.K
            x[12:16] = [K[0, 0], K[1, 1], K[0, 2], K[1, 2]]
            x[16:16 + self.n_dist] = self.intr0.dist[:self.n_dist]
        return x


def refine_hand_eye(detections: Sequence[Detection], T_base_flange: Sequence[np.ndarray],
                    T_flange_camera: np.ndarray, T_base_board: np.ndarray,
                    intrinsics: Intrinsics, *, pose_error: PoseErrorPrior | None = None,
                    refine_intrinsics: bool = False, distortion_model: str = "k1k2p1p2",
                    pixel_sigma: float = DEFAULT_PIXEL_SIGMA,
                    estimate_sigmas: bool = True) -> RefineResult:
    """Refine X = T_flange_camera and T_base_board from initial values (module docstring).

    ``pose_error`` None trusts the arm's poses exactly (deltas fixed at 0). With
    ``estimate_sigmas`` False the given sigmas are used as they are (one round).
    """
    with_delta = pose_error is not None
    prior = pose_error or PoseErrorPrior(estimate=False)
    prob = _Problem(list(detections), [np.asarray(F, float) for F in T_base_flange],
                    np.asarray(T_flange_camera, float), np.asarray(T_base_board, float),
                    intrinsics, DISTORTION_MODELS[distortion_model] if refine_intrinsics else 0,
                    refine_intrinsics, with_delta, float(pixel_sigma),
                    float(prior.translation_m), float(prior.rotation_rad))
    x = prob.x0()
    rounds = VARIANCE_ROUNDS if estimate_sigmas else 1
    iterations = 0
    for r in range(rounds):
        # MINPACK's LM: exact Jacobian, small dense problem, no BLAS-threaded SVD per step.
        sol = least_squares(partial(_residuals, prob), x, jac=partial(_jacobian, prob),
                            method="lm", x_scale="jac", ftol=_FTOL, xtol=_FTOL, gtol=_FTOL,
                            max_nfev=MAX_EVALUATIONS)
        x, iterations = sol.x, iterations + sol.nfev
        if r == rounds - 1:
            break
        prob = _update_sigmas(prob, x, sol.jac, with_delta and prior.estimate)
    return _result(prob, x, iterations)


def _transforms(prob: _Problem, x: np.ndarray):
    xi_X, xi_B, intr, delta = prob.split(x)
    X = prob.X0 @ exp6(xi_X)
    B = prob.B0 @ exp6(xi_B)
    return X, B, prob.intrinsics(intr), delta


def _project(prob: _Problem, det: Detection, X, B, F_true, intr: Intrinsics, jac: bool):
    T_cb = invert(X) @ invert(F_true) @ B
    rvec = cv2.Rodrigues(np.ascontiguousarray(T_cb[:3, :3]))[0]
    uv, J = cv2.projectPoints(det.object_points, rvec, T_cb[:3, 3], intr.K, intr.dist)
    return uv.reshape(-1, 2), (J if jac else None), T_cb


def _residuals(prob: _Problem, x: np.ndarray) -> np.ndarray:
    X, B, intr, delta = _transforms(prob, x)
    out = []
    for i, det in enumerate(prob.detections):
        uv, _, _ = _project(prob, det, X, B, prob.F[i] @ exp6(delta[i]), intr, False)
        out.append(((uv - det.image_points) / prob.sigma_px).ravel())
    if prob.with_delta:
        scale = np.array([prob.sigma_r] * 3 + [prob.sigma_t] * 3)
        out.append((delta / scale).ravel())
    return np.concatenate(out)


def _jacobian(prob: _Problem, x: np.ndarray) -> np.ndarray:
    """Analytic Jacobian of _residuals (dense; a few hundred columns at most)."""
    xi_X, xi_B, _, delta = prob.split(x)
    X, B, intr, _ = _transforms(prob, x)
    M_X, M_B = chart_jacobian(xi_X), chart_jacobian(xi_B)
    rows = sum(2 * len(d) for d in prob.detections)
    J = np.zeros((rows + (6 * prob.n_views if prob.with_delta else 0), prob.n_params))
    R_X = X[:3, :3]
    r0 = 0
    for i, det in enumerate(prob.detections):
        F_true = prob.F[i] @ exp6(delta[i])
        _, Jcv, T_cb = _project(prob, det, X, B, F_true, intr, True)
        n = len(det)
        d_uv_dP = Jcv[:, 3:6].reshape(n, 2, 3)  # d(uv)/d(camera point) = d/d(tvec)
        P_c = det.object_points @ T_cb[:3, :3].T + T_cb[:3, 3]
        P_f = P_c @ R_X.T + X[:3, 3]  # the corner in the (true) flange frame
        # X -> X exp(e): P_c -> P_c - w x P_c - v
        dP_dX = np.concatenate([_skew_rows(P_c), np.broadcast_to(-np.eye(3), (n, 3, 3))], 2)
        # B -> B exp(e): P_c -> P_c + R_cb (w x P_b + v)
        R_cb = T_cb[:3, :3]
        dP_dB = np.concatenate([-R_cb @ _skew_rows(det.object_points),
                                np.broadcast_to(R_cb, (n, 3, 3))], 2)
        blk = slice(r0, r0 + 2 * n)
        J[blk, 0:6] = (d_uv_dP @ dP_dX).reshape(2 * n, 6) @ M_X
        J[blk, 6:12] = (d_uv_dP @ dP_dB).reshape(2 * n, 6) @ M_B
        if prob.refine_intrinsics:
            J[blk, 12:16] = Jcv[:, 6:10]
            J[blk, 16:16 + prob.n_dist] = Jcv[:, 10:10 + prob.n_dist]
        if prob.with_delta:
            # F -> F exp(d) exp(e): P_f -> P_f - w x P_f - v, then P_c = R_X^T (P_f - t_X)
            dPf = np.concatenate([_skew_rows(P_f), np.broadcast_to(-np.eye(3), (n, 3, 3))], 2)
            c = 12 + prob.n_intr + 6 * i
            J[blk, c:c + 6] = (d_uv_dP @ (R_X.T @ dPf)).reshape(2 * n, 6) @ chart_jacobian(
                delta[i])
        r0 += 2 * n
    J[:rows] /= prob.sigma_px
    if prob.with_delta:
        scale = np.array([prob.sigma_r] * 3 + [prob.sigma_t] * 3)
        c0 = 12 + prob.n_intr
        idx = np.arange(6 * prob.n_views)
        J[rows + idx, c0 + idx] = 1.0 / np.tile(scale, prob.n_views)
    return J


def _skew_rows(P: np.ndarray) -> np.ndarray:
    """(n, 3, 3) stack of [p]x for points (n, 3): [p]x w = p x w = -(w x p)."""
    out = np.zeros((len(P), 3, 3))
    out[:, 0, 1], out[:, 0, 2] = -P[:, 2], P[:, 1]
    out[:, 1, 0], out[:, 1, 2] = P[:, 2], -P[:, 0]
    out[:, 2, 0], out[:, 2, 1] = -P[:, 1], P[:, 0]
    return out


def _update_sigmas(prob: _Problem, x: np.ndarray, jac, estimate_pose: bool) -> _Problem:
    """Variance component estimation: pixel sigma from the residuals, pose sigmas from the
    deltas and how much of each delta the images (not the prior) determine."""
    res = _residuals(prob, x)
    n_pix = sum(2 * len(d) for d in prob.detections)
    dof = max(n_pix - 6 * prob.n_views - 12 - prob.n_intr, 1)
    sigma_px = prob.sigma_px * float(np.sqrt(np.sum(res[:n_pix] ** 2) / dof))
    new = replace(prob, sigma_px=sigma_px)
    if not estimate_pose:
        return new
    J = np.asarray(jac)
    cov = np.linalg.pinv(J.T @ J)  # parameter covariance (rad, m, px)
    _, _, _, delta = prob.split(x)
    c0 = 12 + prob.n_intr
    var = np.diag(cov)[c0:].reshape(-1, 6)
    s_r = _variance_component(delta[:, :3], var[:, :3], prob.sigma_r)
    s_t = _variance_component(delta[:, 3:], var[:, 3:], prob.sigma_t)
    return replace(new, sigma_r=max(s_r, SIGMA_FLOOR_R), sigma_t=max(s_t, SIGMA_FLOOR_T))


def _variance_component(d: np.ndarray, var: np.ndarray, sigma: float) -> float:
    """Foerstner's estimate of a prior's sigma: the squared corrections over the prior's
    redundancy, sum(1 - var / sigma^2). It reaches zero (an ideal arm) in a few rounds,
    where the plain EM update only creeps towards it."""
    redundancy = float(np.sum(1.0 - var / sigma**2))
    return math.sqrt(float(np.sum(d**2)) / max(redundancy, 1e-9))


def _result(prob: _Problem, x: np.ndarray, iterations: int) -> RefineResult:
    X, B, intr, delta = _transforms(prob, x)
    per_view, sq = [], []
    for i, det in enumerate(prob.detections):
        uv, _, _ = _project(prob, det, X, B, prob.F[i] @ exp6(delta[i]), intr, False)
        e2 = np.sum((uv - det.image_points) ** 2, axis=1)
        per_view.append(math.sqrt(float(np.mean(e2))))
        sq.append(e2)
    J = _jacobian(prob, x)
    cov = np.linalg.pinv(J.T @ J)[:6, :6]
    M = chart_jacobian(prob.split(x)[0])
    cov_X = M @ cov @ M.T  # in X's own (right-perturbation) frame
    return RefineResult(X, B, intr, delta.copy(), prob.sigma_px, prob.sigma_t, prob.sigma_r,
                        math.sqrt(float(np.mean(np.concatenate(sq)))), np.array(per_view),
                        cov_X, iterations)

