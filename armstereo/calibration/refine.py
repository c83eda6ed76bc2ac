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

With ``board_shape`` the board's own shape is estimated too, because a real print is neither
exactly the size its spec says nor flat: each corner ``P = (x, y, 0)`` of the spec becomes
``(x + s (x - cx), y + s (y - cy), kx (x - cx)^2 + ky (y - cy)^2)`` about the board's centre
``(cx, cy)``, with unknown relative scale error ``s`` and bow curvatures ``kx``, ``ky`` (1/m,
board z). The arm's metric motion makes the scale observable: a board 0.2 % larger than its
spec, taken as the spec, moves the hand-eye by about a millimetre; a bow of half a millimetre
biases the focal length by a tenth of a percent.

The Jacobian is analytic: OpenCV's ``projectPoints`` gives d(uv)/d(camera point) and the
intrinsics' columns; poses are perturbed on the right through :mod:`poses`' chart. Each view's
rows touch only X, the board, the intrinsics and its own delta, so the normal equations are
accumulated view by view (a few hundred unknowns at most) and solved by Levenberg-Marquardt
with Marquardt's diagonal scaling; no dense Jacobian of the whole problem is ever formed.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, replace

import cv2
import numpy as np

from armstereo.calibration.board import Detection
from armstereo.calibration.intrinsics import DISTORTION_MODELS
from armstereo.calibration.poses import chart_jacobian, exp6
from armstereo.camera_model import Intrinsics
from armstereo.errors import ConfigError
from armstereo.transforms import invert, skew_stack

DEFAULT_PIXEL_SIGMA = 0.3  # px, starting value; estimated from the residuals
SIGMA_FLOOR_T = 1e-6  # m: pose-error sigmas never go below these (keeps the prior finite)
SIGMA_FLOOR_R = 1e-6  # rad
VARIANCE_ROUNDS = 4  # fits; the sigmas are re-estimated between them
MAX_ITERATIONS = 100  # Levenberg-Marquardt steps per fit
COST_TOL = 1e-12  # relative cost decrease below which a fit has converged
STEP_TOL = 1e-10  # scaled step norm below which a fit has converged
_LAMBDA_START, _LAMBDA_MIN, _LAMBDA_MAX = 1e-4, 1e-12, 1e10


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
    # (s, kx, ky) of the board's shape (module doc) and the centre it is taken about (board
    # frame, m); None when the board was taken as its spec says.
    board_shape: np.ndarray | None = None
    board_center: np.ndarray | None = None

    def object_points(self, det: Detection) -> np.ndarray:
        """``det``'s corners on the board as this fit found it (board frame, m)."""
        if self.board_shape is None:
            return det.object_points
        return shaped_points(det.object_points, self.board_shape, self.board_center)


def shaped_points(P: np.ndarray, shape: np.ndarray, center: np.ndarray) -> np.ndarray:
    """Board-frame corners (N, 3) of the spec moved by ``shape`` = (s, kx, ky) about
    ``center`` (cx, cy) (module doc)."""
    dx, dy = P[:, 0] - center[0], P[:, 1] - center[1]
    out = np.array(P, dtype=float, copy=True)
    out[:, 0] += shape[0] * dx
    out[:, 1] += shape[0] * dy
    out[:, 2] += shape[1] * dx * dx + shape[2] * dy * dy
    return out


def _shape_columns(P: np.ndarray, center: np.ndarray) -> np.ndarray:
    """(N, 3, 3): d(shaped point)/d(s, kx, ky) (the model is linear in them)."""
    dx, dy = P[:, 0] - center[0], P[:, 1] - center[1]
    J = np.zeros((len(P), 3, 3))
    J[:, 0, 0], J[:, 1, 0] = dx, dy
    J[:, 2, 1], J[:, 2, 2] = dx * dx, dy * dy
    return J


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
    shape0: np.ndarray | None = None  # (s, kx, ky) start; None: the board as its spec says
    center: np.ndarray | None = None  # board-frame centre the shape is taken about

    @property
    def n_views(self) -> int:
        return len(self.F)

    @property
    def n_intr(self) -> int:
        return 4 + self.n_dist if self.refine_intrinsics else 0

    @property
    def n_shape(self) -> int:
        return 0 if self.shape0 is None else 3

    @property
    def n_shared(self) -> int:
        return 12 + self.n_intr + self.n_shape

    @property
    def n_params(self) -> int:
        return self.n_shared + (6 * self.n_views if self.with_delta else 0)

    def split(self, x: np.ndarray):
        """(xi_X, xi_B, intrinsics, delta (V, 6), board shape (3,) or None) of x."""
        xi_X, xi_B = x[:6], x[6:12]
        intr = x[12:12 + self.n_intr]
        shape = x[12 + self.n_intr:self.n_shared] if self.n_shape else None
        delta = x[self.n_shared:].reshape(-1, 6) if self.with_delta else \
            np.zeros((self.n_views, 6))
        return xi_X, xi_B, intr, delta, shape

    def points(self, det: Detection, shape: np.ndarray | None) -> np.ndarray:
        return det.object_points if shape is None else shaped_points(det.object_points,
                                                                     shape, self.center)

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
        if self.n_shape:
            x[12 + self.n_intr:self.n_shared] = self.shape0
        return x


def refine_hand_eye(detections: Sequence[Detection], T_base_flange: Sequence[np.ndarray],
                    T_flange_camera: np.ndarray, T_base_board: np.ndarray,
                    intrinsics: Intrinsics, *, pose_error: PoseErrorPrior | None = None,
                    refine_intrinsics: bool = False, distortion_model: str = "k1k2",
                    pixel_sigma: float = DEFAULT_PIXEL_SIGMA,
                    estimate_sigmas: bool = True, cost_tol: float = COST_TOL,
                    board_shape: bool = False, shape0: Sequence[float] | None = None,
                    board_center: Sequence[float] | None = None) -> RefineResult:
    """Refine X = T_flange_camera and T_base_board from initial values (module docstring).

    ``pose_error`` None trusts the arm's poses exactly (deltas fixed at 0). With
    ``estimate_sigmas`` False the given sigmas are used as they are (one fit).
    ``board_shape`` also estimates the board's scale error and bow (module docstring),
    starting from ``shape0`` (default none) about ``board_center`` (board frame; default the
    middle of the detected corners).
    """
    with_delta = pose_error is not None
    prior = pose_error or PoseErrorPrior(estimate=False)
    dets = list(detections)
    center = None
    if board_shape:
        center = (np.asarray(board_center, float) if board_center is not None else
                  np.mean(np.concatenate([d.object_points for d in dets])[:, :2], axis=0))
    prob = _Problem(dets, [np.asarray(F, float) for F in T_base_flange],
                    np.asarray(T_flange_camera, float), np.asarray(T_base_board, float),
                    intrinsics, DISTORTION_MODELS[distortion_model] if refine_intrinsics else 0,
                    refine_intrinsics, with_delta, float(pixel_sigma),
                    float(prior.translation_m), float(prior.rotation_rad),
                    None if not board_shape else np.asarray(shape0 if shape0 is not None
                                                            else np.zeros(3), float),
                    center)
    x = prob.x0()
    rounds = VARIANCE_ROUNDS if estimate_sigmas else 1
    iterations = 0
    for r in range(rounds):
        x, n_it = _levenberg_marquardt(prob, x, cost_tol)
        iterations += n_it
        if r == rounds - 1:
            break
        prob = _update_sigmas(prob, x, with_delta and prior.estimate)
    return _result(prob, x, iterations)


def _levenberg_marquardt(prob: _Problem, x: np.ndarray, cost_tol: float):
    """Minimise |residuals|^2 from x with Marquardt's damping lambda * diag(J^T J); returns
    (x, iterations)."""
    cost = _cost(prob, x)
    lam = _LAMBDA_START
    for it in range(1, MAX_ITERATIONS + 1):
        normal = _normal_equations(prob, x)
        while True:
            step = normal.solve(lam)
            x_new = x + step
            cost_new = _cost_or_inf(prob, x_new)
            if cost_new <= cost:
                break
            lam *= 10.0
            if lam > _LAMBDA_MAX:
                return x, it  # no step lowers the cost: x is a minimum to working precision
        lam = max(lam * 0.1, _LAMBDA_MIN)
        scale = normal.scale()
        small_step = float(np.linalg.norm(step * scale)) <= STEP_TOL * (
            1.0 + float(np.linalg.norm(x * scale)))
        done = cost - cost_new <= cost_tol * cost or small_step
        x, cost = x_new, cost_new
        if done:
            return x, it
    return x, MAX_ITERATIONS


@dataclass
class _Normal:
    """Normal equations J^T J dx = -J^T r split into the shared unknowns (X, board,
    intrinsics: block A, gradient ga) and the per-view deltas (6x6 blocks D, gradients gd,
    couplings C (V, p, 6)). Solved by the Schur complement on the deltas, so no system is
    larger than the shared unknowns (at most 21); small solves also keep multi-threaded BLAS
    from spinning on a busy machine."""

    A: np.ndarray
    ga: np.ndarray
    C: np.ndarray
    D: np.ndarray
    gd: np.ndarray

    def scale(self) -> np.ndarray:
        diag = np.concatenate([np.diag(self.A), np.einsum("vii->vi", self.D).ravel()])
        return np.sqrt(np.maximum(diag, 1e-300))

    def solve(self, lam: float) -> np.ndarray:
        """The step dx of (J^T J + lam diag(J^T J)) dx = -J^T r."""
        A = self.A + lam * np.diag(np.diag(self.A))
        if self.D.shape[0] == 0:
            return np.linalg.solve(A, -self.ga)
        D = self.D + lam * np.einsum("vij,vi->vij", np.eye(6)[None], np.einsum("vii->vi", self.D))
        Dinv = np.linalg.inv(D)
        CDinv = np.einsum("vpi,vij->vpj", self.C, Dinv)
        S = A - np.einsum("vpi,vqi->pq", CDinv, self.C)
        rhs = -self.ga + np.einsum("vpi,vi->p", CDinv, self.gd)
        da = np.linalg.solve(S, rhs)
        dd = -np.einsum("vij,vj->vi", Dinv, self.gd + np.einsum("vpi,p->vi", self.C, da))
        return np.concatenate([da, dd.ravel()])

    def covariance(self) -> tuple[np.ndarray, np.ndarray]:
        """(J^T J)^-1: the shared block (p, p) and the deltas' diagonal 6x6 blocks (V, 6, 6)."""
        if self.D.shape[0] == 0:
            return np.linalg.pinv(self.A), self.D.copy()
        Dinv = np.linalg.inv(self.D)
        CDinv = np.einsum("vpi,vij->vpj", self.C, Dinv)
        cov_a = np.linalg.pinv(self.A - np.einsum("vpi,vqi->pq", CDinv, self.C))
        cov_d = Dinv + np.einsum("vpi,pq,vqj->vij", CDinv, cov_a, CDinv)
        return cov_a, cov_d


def _transforms(prob: _Problem, x: np.ndarray):
    xi_X, xi_B, intr, delta, shape = prob.split(x)
    X = prob.X0 @ exp6(xi_X)
    B = prob.B0 @ exp6(xi_B)
    return X, B, prob.intrinsics(intr), delta, shape


def _project(P: np.ndarray, X, B, F_true, intr: Intrinsics, jac: bool):
    """Corners ``P`` (board frame) projected from the true flange pose ``F_true``."""
    T_cb = invert(X) @ invert(F_true) @ B
    rvec = cv2.Rodrigues(np.ascontiguousarray(T_cb[:3, :3]))[0]
    uv, J = cv2.projectPoints(P, rvec, T_cb[:3, 3], intr.K, intr.dist)
    return uv.reshape(-1, 2), (J if jac else None), T_cb


def _pixel_residuals(prob: _Problem, x: np.ndarray) -> list[np.ndarray]:
    """Per view, (N, 2) pixel errors (projected minus detected), not divided by sigma."""
    X, B, intr, delta, shape = _transforms(prob, x)
    return [_project(prob.points(det, shape), X, B, prob.F[i] @ exp6(delta[i]), intr,
                     False)[0] - det.image_points
            for i, det in enumerate(prob.detections)]


def _prior_scale(prob: _Problem) -> np.ndarray:
    return np.array([prob.sigma_r] * 3 + [prob.sigma_t] * 3)


def _residuals(prob: _Problem, x: np.ndarray) -> np.ndarray:
    """All whitened residuals: pixels / sigma_px view by view, then delta / prior sigma."""
    out = [(r / prob.sigma_px).ravel() for r in _pixel_residuals(prob, x)]
    if prob.with_delta:
        out.append((prob.split(x)[3] / _prior_scale(prob)).ravel())
    return np.concatenate(out)


def _cost_or_inf(prob: _Problem, x: np.ndarray) -> float:
    """The cost, or infinity where a step leaves the valid cameras (a focal length through
    zero, non-finite numbers): such a step is rejected like one that raises the cost, so the
    fit never walks into an invalid camera."""
    if not np.all(np.isfinite(x)):
        return math.inf
    try:
        cost = _cost(prob, x)
    except ConfigError:  # Intrinsics refuses the camera matrix
        return math.inf
    return cost if math.isfinite(cost) else math.inf


def _cost(prob: _Problem, x: np.ndarray) -> float:
    r = _residuals(prob, x)
    return float(r @ r)


def _view_blocks(prob: _Problem, x: np.ndarray):
    """Per view: (column indices, whitened Jacobian rows (2N, k), whitened residuals (2N,))."""
    xi_X, xi_B, _, delta, _ = prob.split(x)
    X, B, intr, _, shape = _transforms(prob, x)
    M_X, M_B = chart_jacobian(xi_X), chart_jacobian(xi_B)
    R_X = X[:3, :3]
    shared = list(range(prob.n_shared))
    for i, det in enumerate(prob.detections):
        P_b = prob.points(det, shape)
        uv, Jcv, T_cb = _project(P_b, X, B, prob.F[i] @ exp6(delta[i]), intr, True)
        n = len(det)
        d_uv_dP = Jcv[:, 3:6].reshape(n, 2, 3)  # d(uv)/d(camera point) = d/d(tvec)
        P_c = P_b @ T_cb[:3, :3].T + T_cb[:3, 3]
        P_f = P_c @ R_X.T + X[:3, 3]  # the corner in the (true) flange frame
        minus_I = np.broadcast_to(-np.eye(3), (n, 3, 3))
        blocks = [
            # X -> X exp(e): P_c -> P_c - w x P_c - v
            (d_uv_dP @ np.concatenate([skew_stack(P_c), minus_I], 2)).reshape(2 * n, 6) @ M_X,
            # B -> B exp(e): P_c -> P_c + R_cb (w x P_b + v)
            (d_uv_dP @ np.concatenate([-T_cb[:3, :3] @ skew_stack(P_b),
                                       np.broadcast_to(T_cb[:3, :3], (n, 3, 3))], 2)
             ).reshape(2 * n, 6) @ M_B,
        ]
        if prob.refine_intrinsics:
            blocks.append(Jcv[:, 6:10])
            blocks.append(Jcv[:, 10:10 + prob.n_dist])
        if prob.n_shape:
            # the shape moves the corner on the board: P_c -> P_c + R_cb dP
            blocks.append((d_uv_dP @ (T_cb[:3, :3] @ _shape_columns(det.object_points,
                                                                   prob.center))
                           ).reshape(2 * n, 3))
        cols = shared
        if prob.with_delta:
            # F -> F exp(d) exp(e): P_f -> P_f - w x P_f - v, then P_c = R_X^T (P_f - t_X)
            dPf = np.concatenate([skew_stack(P_f), minus_I], 2)
            blocks.append((d_uv_dP @ (R_X.T @ dPf)).reshape(2 * n, 6)
                          @ chart_jacobian(delta[i]))
            c = prob.n_shared + 6 * i
            cols = shared + list(range(c, c + 6))
        J = np.concatenate(blocks, axis=1) / prob.sigma_px
        r = ((uv - det.image_points) / prob.sigma_px).ravel()
        yield np.array(cols), J, r


def _normal_equations(prob: _Problem, x: np.ndarray) -> _Normal:
    """J^T J and J^T r of the whitened problem, accumulated view by view."""
    p = prob.n_shared
    V = prob.n_views if prob.with_delta else 0
    A, ga = np.zeros((p, p)), np.zeros(p)
    C, D, gd = np.zeros((V, p, 6)), np.zeros((V, 6, 6)), np.zeros((V, 6))
    for i, (_, J, r) in enumerate(_view_blocks(prob, x)):
        Ja = J[:, :p]
        A += Ja.T @ Ja
        ga += Ja.T @ r
        if V:
            Jd = J[:, p:]
            C[i] = Ja.T @ Jd
            D[i] = Jd.T @ Jd
            gd[i] = Jd.T @ r
    if V:
        w = 1.0 / _prior_scale(prob)
        D[:, np.arange(6), np.arange(6)] += w**2
        gd += prob.split(x)[3] * w**2
    return _Normal(A, ga, C, D, gd)


def _jacobian(prob: _Problem, x: np.ndarray) -> np.ndarray:
    """The dense whitened Jacobian of _residuals (for checks; the solver never forms it)."""
    rows = []
    for cols, J, _ in _view_blocks(prob, x):
        full = np.zeros((len(J), prob.n_params))
        full[:, cols] = J
        rows.append(full)
    if prob.with_delta:
        c0 = prob.n_shared
        prior = np.zeros((6 * prob.n_views, prob.n_params))
        idx = np.arange(6 * prob.n_views)
        prior[idx, c0 + idx] = 1.0 / np.tile(_prior_scale(prob), prob.n_views)
        rows.append(prior)
    return np.concatenate(rows)


def _update_sigmas(prob: _Problem, x: np.ndarray, estimate_pose: bool) -> _Problem:
    """Variance component estimation: pixel sigma from the residuals, pose sigmas from the
    deltas and how much of each delta the images (not the prior) determine."""
    pix = np.concatenate([r.ravel() for r in _pixel_residuals(prob, x)])
    dof = max(len(pix) - 6 * prob.n_views - prob.n_shared, 1)
    new = replace(prob, sigma_px=float(np.sqrt(np.sum(pix**2) / dof)))
    if not estimate_pose:
        return new
    _, cov_d = _normal_equations(prob, x).covariance()
    delta = prob.split(x)[3]
    var = np.einsum("vii->vi", cov_d)
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
    X, B, intr, delta, shape = _transforms(prob, x)
    errs = [np.sum(r**2, axis=1) for r in _pixel_residuals(prob, x)]
    per_view = np.array([math.sqrt(float(np.mean(e))) for e in errs])
    M = chart_jacobian(prob.split(x)[0])
    cov_a, _ = _normal_equations(prob, x).covariance()
    cov_X = M @ cov_a[:6, :6] @ M.T  # in X's own (right-perturbation) frame
    return RefineResult(X, B, intr, delta.copy(), prob.sigma_px, prob.sigma_t, prob.sigma_r,
                        math.sqrt(float(np.mean(np.concatenate(errs)))), per_view, cov_X,
                        iterations, None if shape is None else shape.copy(),
                        None if prob.center is None else prob.center.copy())
