"""Joint refinement: analytic Jacobian, structured solver, and the arm-pose-error trap."""

from __future__ import annotations

import numpy as np
import pytest

from armstereo.calibration import refine as R
from armstereo.calibration.board import parse_board
from armstereo.calibration.handeye import closed_form_all
from armstereo.calibration.intrinsics import board_pose, calibrate_intrinsics
from armstereo.calibration.poses import exp6, mean_pose, pose_difference
from armstereo.calibration.refine import PoseErrorPrior, refine_hand_eye
from armstereo.calibration.synthetic import simulate_session

from .conftest import BOARD_SPEC


def _start(session, intrinsics=None):
    """Closed-form start (Park) with calibrateCamera intrinsics, as the pipeline does."""
    fit = calibrate_intrinsics(session.detections, (640, 480))
    intr = intrinsics or fit.intrinsics
    T_cb = [board_pose(d, intr) for d in session.detections]
    X0 = closed_form_all(session.T_base_flange_reported, T_cb)["park"].T_flange_camera
    B0 = mean_pose([F @ X0 @ C
                    for F, C in zip(session.T_base_flange_reported, T_cb, strict=True)])
    return X0, B0, intr


@pytest.fixture(scope="module")
def small_session(ur5e):
    return simulate_session(ur5e, parse_board("chessboard:10x7:0.03"), n_views=6, seed=3)


def test_jacobian_matches_finite_differences(small_session):
    s = small_session
    X0, B0, intr = _start(s)
    prob = R._Problem(s.detections, s.T_base_flange_reported, X0, B0, intr, 2, True, True,
                      0.3, 0.0005, 0.0005)
    rng = np.random.default_rng(0)
    x = prob.x0() + np.concatenate([rng.normal(size=12) * 1e-3, np.zeros(prob.n_intr),
                                    rng.normal(size=6 * prob.n_views) * 1e-3])
    J = R._jacobian(prob, x)
    Jn = np.empty_like(J)
    for k in range(len(x)):
        h = 1e-6 * max(1.0, abs(x[k]))
        xp, xm = x.copy(), x.copy()
        xp[k] += h
        xm[k] -= h
        Jn[:, k] = (R._residuals(prob, xp) - R._residuals(prob, xm)) / (2 * h)
    assert np.abs(J - Jn).max() < 1e-6 * np.abs(Jn).max()
    # the Schur-complement solve equals the dense damped normal equations
    r = R._residuals(prob, x)
    H, g = J.T @ J, J.T @ r
    for lam in (0.0, 1e-2):
        dense = -np.linalg.solve(H + lam * np.diag(np.diag(H)), g)
        np.testing.assert_allclose(R._normal_equations(prob, x).solve(lam), dense,
                                   rtol=1e-7, atol=1e-10 * np.abs(dense).max())


def test_exact_data_is_recovered_exactly(ur5e):
    s = simulate_session(ur5e, parse_board(BOARD_SPEC), n_views=8, arm_error="ideal",
                         pixel_noise=0.0, seed=4)
    X0 = s.true_mount.T_flange_camera @ exp6([0.01, -0.01, 0.02, 0.003, -0.002, 0.004])
    B0 = s.T_base_board @ exp6([0.01, 0.0, -0.01, 0.002, 0.003, -0.001])
    K0 = s.true_mount.intrinsics
    res = refine_hand_eye(s.detections, s.T_base_flange_reported, X0, B0, K0,
                          pose_error=PoseErrorPrior(), refine_intrinsics=True)
    dt, dr = pose_difference(res.T_flange_camera, s.true_mount.T_flange_camera)
    assert dt < 1e-8 and dr < 1e-6
    assert res.rms_px < 1e-6
    np.testing.assert_allclose(res.intrinsics.K, K0.K, atol=1e-6)


def _errors(session, **kw):
    X0, B0, intr = _start(session)
    res = refine_hand_eye(session.detections, session.T_base_flange_reported, X0, B0, intr,
                          **kw)
    return pose_difference(res.T_flange_camera, session.true_mount.T_flange_camera), res


def test_trusting_millimetre_wrong_kinematics_is_worse_than_closed_form(ur5e):
    """The issue's trap: nominal kinematics of an arm whose real DH parameters differ."""
    board = parse_board(BOARD_SPEC)
    closed, trusting, modelled = [], [], []
    for seed in range(3):
        s = simulate_session(ur5e, board, arm_error="nominal_kinematics", seed=seed)
        X0, _, _ = _start(s)
        closed.append(pose_difference(X0, s.true_mount.T_flange_camera)[1])
        trusting.append(_errors(s, pose_error=None, refine_intrinsics=True)[0][1])
        (_, rot), res = _errors(s, pose_error=PoseErrorPrior(), refine_intrinsics=True)
        modelled.append(rot)
        assert res.pose_sigma_t > 0.0002  # it noticed: a few tenths of a millimetre per view
    assert np.mean(trusting) > np.mean(closed)
    assert np.mean(modelled) < 0.6 * np.mean(trusting)


def test_an_ideal_arm_ends_up_trusted(ur5e):
    s = simulate_session(ur5e, parse_board(BOARD_SPEC), arm_error="ideal", seed=1)
    _, modelled = _errors(s, pose_error=PoseErrorPrior(), refine_intrinsics=True)
    _, trusting = _errors(s, pose_error=None, refine_intrinsics=True)
    assert modelled.pose_sigma_t < 0.00005 and np.degrees(modelled.pose_sigma_r) < 0.005
    dt, dr = pose_difference(modelled.T_flange_camera, trusting.T_flange_camera)
    assert dt < 0.0001 and dr < 0.03  # well inside either's own error (~0.2 mm, ~0.05 deg)
    assert modelled.pixel_sigma == pytest.approx(0.3, rel=0.1)


def test_refining_intrinsics_with_the_arm_removes_the_same_view_bias(ur5e):
    """The other trap: intrinsics fitted to the hand-eye views alone bias the hand-eye (by
    millimetres with a 54-corner board)."""
    board = parse_board("chessboard:10x7:0.03")
    fixed, joint = [], []
    for seed in range(3):
        s = simulate_session(ur5e, board, arm_error="ideal", seed=seed)
        fixed.append(_errors(s, pose_error=None, refine_intrinsics=False)[0][0])
        joint.append(_errors(s, pose_error=None, refine_intrinsics=True)[0][0])
    assert np.mean(joint) < 0.5 * np.mean(fixed)


def _shaped_session(ur5e, scale_error: float, curvature: tuple[float, float]):
    """A session whose board is printed ``1 + scale_error`` times its spec and bowed by
    ``curvature`` (1/m, board z): the detections carry the spec's object points."""
    import cv2

    from armstereo.calibration.board import Detection
    from armstereo.transforms import invert

    s = simulate_session(ur5e, parse_board("chessboard:17x12:0.016"), n_views=12, seed=4,
                         arm_error="ideal", pixel_noise=0.05)
    shape = np.array([scale_error, *curvature])
    center = s.board.center[:2]
    rng = np.random.default_rng(1)
    dets = []
    for F in s.T_base_flange_true:
        T_cb = invert(F @ s.true_mount.T_flange_camera) @ s.T_base_board
        P = R.shaped_points(s.board.object_points, shape, center)
        rvec = cv2.Rodrigues(np.ascontiguousarray(T_cb[:3, :3]))[0]
        uv, _ = cv2.projectPoints(P, rvec, T_cb[:3, 3], s.true_mount.intrinsics.K,
                                  s.true_mount.intrinsics.dist)
        uv = uv.reshape(-1, 2) + rng.normal(size=(len(P), 2)) * 0.05
        dets.append(Detection(np.arange(len(P)), uv, s.board.object_points.copy()))
    return s, dets, shape


def test_board_shape_columns_match_finite_differences(small_session):
    s = small_session
    X0, B0, intr = _start(s)
    prob = R._Problem(s.detections, s.T_base_flange_reported, X0, B0, intr, 2, True, True,
                      0.3, 0.0005, 0.0005, np.array([1e-3, 0.02, -0.01]),
                      s.board.center[:2])
    rng = np.random.default_rng(2)
    x = prob.x0() + np.concatenate([rng.normal(size=12) * 1e-3, np.zeros(prob.n_intr),
                                    np.zeros(3), rng.normal(size=6 * prob.n_views) * 1e-3])
    J = R._jacobian(prob, x)
    cols = range(12 + prob.n_intr, prob.n_shared)
    for k in cols:
        h = 1e-6
        xp, xm = x.copy(), x.copy()
        xp[k] += h
        xm[k] -= h
        num = (R._residuals(prob, xp) - R._residuals(prob, xm)) / (2 * h)
        assert np.abs(J[:, k] - num).max() < 1e-5 * max(np.abs(num).max(), 1.0)


def test_a_misprinted_bowed_board_is_measured_instead_of_biasing_the_hand_eye(ur5e):
    s, dets, shape = _shaped_session(ur5e, 0.003, (0.02, 0.01))
    X0, B0, intr = _start(s)
    errors = {}
    for board_shape in (False, True):
        res = refine_hand_eye(dets, s.T_base_flange_reported, X0, B0, intr,
                              pose_error=PoseErrorPrior(), refine_intrinsics=True,
                              board_shape=board_shape, board_center=s.board.center[:2])
        errors[board_shape] = pose_difference(res.T_flange_camera,
                                              s.true_mount.T_flange_camera)
        if board_shape:
            assert res.board_shape[0] == pytest.approx(shape[0], abs=2e-4)
            np.testing.assert_allclose(res.board_shape[1:], shape[1:], atol=0.004)
            f_true = s.true_mount.intrinsics.fx
            assert abs(res.intrinsics.fx / f_true - 1) < 5e-4
    # taken as its spec, the 0.3 % larger board moves the hand-eye by about a millimetre
    assert errors[False][0] > 5e-4 and errors[True][0] < 0.2 * errors[False][0]
