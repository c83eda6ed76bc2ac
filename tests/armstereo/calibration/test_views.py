"""View planning: diverse, reachable poses that keep the board in view; a pure function."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from armstereo.calibration.board import parse_board, render_board_view
from armstereo.calibration.checks import CalibrationInputError
from armstereo.calibration.poses import pose_difference
from armstereo.calibration.views import (
    ViewPlanSettings,
    board_in_start_view,
    plan_calibration_views,
)
from armstereo.errors import ConfigError, PreflightError
from armstereo.robot.arm_model import ArmModel, ready_configuration
from armstereo.transforms import invert, make_T

from .conftest import BOARD_SPEC

BOARD = parse_board(BOARD_SPEC)


def _start_view(model):
    q0 = ready_configuration("ur5e")
    T_cb = make_T(np.eye(3), np.array([0.01, -0.01, 0.45]) - BOARD.center)
    return q0, T_cb


def test_default_plan_is_reachable_diverse_and_keeps_the_board_in_view(ur5e):
    q0, T_cb = _start_view(ur5e)
    plan = plan_calibration_views(ur5e, q0, BOARD, T_camera_board_start=T_cb)
    assert len(plan.views) == 15
    np.testing.assert_allclose(plan.views[0].q, q0)
    intr = ur5e.mount.intrinsics
    w, h = BOARD.size_m
    outline = np.array([[0, 0, 0], [w, 0, 0], [w, h, 0], [0, h, 0]], dtype=float)
    centre = (plan.T_base_board @ np.append(BOARD.center, 1.0))[:3]
    for k, v in enumerate(plan.views):
        assert ur5e.within_limits(v.q, 0.05)
        assert ur5e.sigma_min(v.q) >= 0.02
        np.testing.assert_allclose(ur5e.flange_pose(v.q), v.T_base_flange, atol=1e-9)
        np.testing.assert_allclose(ur5e.camera_pose(v.q), v.T_base_camera, atol=1e-6)
        # every view but the start looks straight at the board's centre
        to_centre = centre - v.T_base_camera[:3, 3]
        miss = np.linalg.norm(np.cross(to_centre, v.T_base_camera[:3, 2]))
        assert k == 0 or miss < 1e-6
        T = invert(v.T_base_camera) @ plan.T_base_board
        uv, _ = cv2.projectPoints(outline, cv2.Rodrigues(T[:3, :3])[0], T[:3, 3], intr.K,
                                  intr.dist)
        uv = uv.reshape(-1, 2)
        assert np.all(uv >= 0) and np.all(uv[:, 0] < intr.width) and np.all(uv[:, 1] < intr.height)
    tilts = [v for v in plan.views if v.tilt_deg > 5]
    axes = {round(v.azimuth_deg) % 180 for v in tilts}
    assert len(axes) >= 2 and max(abs(math.sin(math.radians(a - b))) for a in axes
                                  for b in axes) > 0.5  # at least two non-parallel tilt axes
    assert min(v.roll_deg for v in plan.views) < -10 and max(v.roll_deg for v in plan.views) > 10
    assert len({round(v.distance_m, 3) for v in plan.views}) >= 3
    assert plan.diversity.axis_spread_deg > 45 and plan.diversity.max_rotation_deg > 40
    assert plan.diversity.usable_pairs >= 0.9 * plan.diversity.pairs
    assert "calibration plan: 15 views" in plan.describe()[0]


def test_planning_is_a_pure_function(ur5e):
    q0, T_cb = _start_view(ur5e)
    a = plan_calibration_views(ur5e, q0, BOARD, T_camera_board_start=T_cb)
    b = plan_calibration_views(ur5e, q0.copy(), BOARD, T_camera_board_start=T_cb.copy())
    for va, vb in zip(a.views, b.views, strict=True):
        np.testing.assert_array_equal(va.q, vb.q)
    np.testing.assert_array_equal(q0, ready_configuration("ur5e"))  # input untouched


def test_without_a_measured_start_view_the_board_is_assumed_ahead(ur5e):
    plan = plan_calibration_views(ur5e, ready_configuration("ur5e"), BOARD,
                                  settings=ViewPlanSettings(n_views=8))
    assert len(plan.views) == 8


@pytest.mark.parametrize("settings, words", [
    (ViewPlanSettings(n_views=3), "--views"),
    (ViewPlanSettings(max_tilt_deg=80), "tilt"),
    (ViewPlanSettings(max_roll_deg=-5), "roll"),
    (ViewPlanSettings(distance_factors=()), "distance"),
])
def test_bad_settings_are_config_errors(ur5e, settings, words):
    with pytest.raises(ConfigError, match=words):
        plan_calibration_views(ur5e, ready_configuration("ur5e"), BOARD, settings=settings)


def test_unusable_start_poses_are_refused_before_anything_moves(ur5e):
    q0, T_cb = _start_view(ur5e)
    behind = make_T(np.eye(3), [0.0, 0.0, -0.4])
    with pytest.raises(PreflightError, match="start pose"):
        plan_calibration_views(ur5e, q0, BOARD, T_camera_board_start=behind)
    near_limit = q0.copy()
    near_limit[3] = ur5e.upper[3] - 0.01
    with pytest.raises(PreflightError, match="start pose"):
        plan_calibration_views(ur5e, near_limit, BOARD, T_camera_board_start=T_cb)


def test_too_many_views_for_the_space_is_a_preflight_error(ur5e):
    q0, T_cb = _start_view(ur5e)
    big = parse_board("chessboard:13x10:0.03")  # fills the image: hardly any view fits
    with pytest.raises(PreflightError, match="views pass the checks") as info:
        plan_calibration_views(ur5e, q0, big, T_camera_board_start=make_T(
            np.eye(3), np.array([0.0, 0.0, 0.45]) - big.center),
            settings=ViewPlanSettings(n_views=30))
    assert "\n" not in str(info.value)


def test_a_model_without_mount_cannot_plan():
    bare = ArmModel.load("ur5e")
    with pytest.raises(ConfigError, match="mount"):
        plan_calibration_views(bare, ready_configuration("ur5e"), BOARD)


def test_the_start_view_locates_the_board_or_says_what_to_do(ur5e):
    _, T_cb = _start_view(ur5e)
    intr = ur5e.mount.intrinsics
    img = render_board_view(BOARD, intr, T_cb, supersample=2)
    dt, dr = pose_difference(board_in_start_view(img, BOARD, intr), T_cb)
    assert dt < 0.001 and dr < 0.1
    with pytest.raises(CalibrationInputError, match="not found in the start image"):
        board_in_start_view(np.full((480, 640), 90, np.uint8), BOARD, intr)
