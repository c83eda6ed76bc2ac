"""Tours of joint moves: capture's pre-flight checks on every joint path, speeds that keep the
flange and camera under the linear caps, and the refusals."""

from __future__ import annotations

import numpy as np
import pytest

from armstereo.capture.plan import Workspace
from armstereo.capture.tour import TourSettings, plan_tour
from armstereo.devices import MAX_JOINT_SPEED, MotionLimits
from armstereo.errors import ConfigError, PreflightError
from armstereo.kinematics import ArmModel
from drivers.mock.start_poses import table_start


@pytest.fixture(scope="module")
def model() -> ArmModel:
    return ArmModel.load("ur5e", mount="default_wrist_camera")


@pytest.fixture(scope="module")
def views(model):
    """The start pose and three nearby views (wrist turns and a shoulder swing)."""
    q0 = table_start(model)
    offsets = [np.zeros(6), [0.15, 0.0, 0.0, 0.1, 0.0, 0.6], [-0.1, 0.05, -0.05, 0.0, 0.2, -0.5],
               [0.0, -0.1, 0.1, -0.1, 0.0, 0.0]]
    return q0, [q0 + np.asarray(o) for o in offsets]


def _failed(plan) -> list[str]:
    return [c.name for c in plan.checks if not c.ok]


def test_every_move_is_checked_and_the_tool_stays_under_the_linear_cap(model, views):
    q0, qs = views
    lim = MotionLimits(linear_speed=0.05, linear_acceleration=0.25)
    plan = plan_tour(model, q0, qs, TourSettings(limits=lim, settle_s=0.2))
    assert plan.ok, plan.describe()
    assert [c.name for c in plan.checks] == ["speed caps", "start pose", "joint limits",
                                             "singularity", "workspace", "joint travel",
                                             "tool speed"]
    # view 0 is the start pose: no move to it; then 1, 2, 3 and back home
    assert [(m.src, m.dst) for m in plan.moves] == [(0, 1), (1, 2), (2, 3), (3, -1)]
    assert plan.move_to(0) is None and plan.move_home.dst == -1
    for m in plan.moves:
        assert 0 < m.speed <= lim.joint_speed and 0 < m.acceleration <= lim.joint_acceleration
        assert m.peak_tool_speed <= lim.linear_speed + 1e-12
        np.testing.assert_allclose(m.travel_rad, np.abs(m.q_to - m.q_from).max())
        # the lever is the tool's displacement per radian of the leading joint: moving the
        # fastest point of flange or camera at the cap needs exactly this joint speed
        if m.speed < lim.joint_speed:
            assert m.speed * m.lever_m == pytest.approx(lim.linear_speed)
    expected = sum(m.duration_s for m in plan.moves) + 4 * 0.2
    assert plan.duration_s == pytest.approx(expected)
    text = "\n".join(plan.describe())
    assert "move 3 -> start" in text and "[ok] tool speed" in text


def test_slower_linear_cap_slows_the_joints(model, views):
    q0, qs = views
    fast = plan_tour(model, q0, qs, TourSettings(limits=MotionLimits(linear_speed=0.1)))
    slow = plan_tour(model, q0, qs, TourSettings(limits=MotionLimits(linear_speed=0.02)))
    for a, b in zip(fast.moves, slow.moves, strict=True):
        assert b.speed < a.speed and b.duration_s > a.duration_s


def test_workspace_travel_and_caps_are_refused_before_anything_moves(model, views):
    q0, qs = views
    cam = model.camera_pose(q0)[:3, 3]
    box = Workspace(tuple(cam - 0.01), tuple(cam + 0.01))  # the flange is outside it
    plan = plan_tour(model, q0, qs, TourSettings(workspace=box))
    assert _failed(plan) == ["workspace"]
    with pytest.raises(PreflightError, match="'workspace' failed.*nothing moved"):
        plan.require_ok()
    assert _failed(plan_tour(model, q0, qs, TourSettings(max_joint_travel=0.3))) == [
        "joint travel"]
    too_fast = MotionLimits(joint_speed=MAX_JOINT_SPEED * 2)
    assert "speed caps" in _failed(plan_tour(model, q0, qs, TourSettings(limits=too_fast)))


def test_views_near_a_joint_limit_or_a_singularity_are_refused(model, views):
    q0, qs = views
    near_limit = qs[1].copy()
    near_limit[5] = model.upper[5] - 0.01
    assert "joint limits" in _failed(plan_tour(model, q0, [qs[0], near_limit]))
    stretched = q0.copy()
    stretched[4] = 0.0  # wrist 2 at zero: wrist singularity
    assert "singularity" in _failed(plan_tour(model, q0, [qs[0], stretched]))


def test_bad_settings_are_config_errors(model, views):
    q0, qs = views
    with pytest.raises(ConfigError, match="--settle"):
        plan_tour(model, q0, qs, TourSettings(settle_s=-1.0))
    with pytest.raises(ConfigError, match="--speed"):
        plan_tour(model, q0, qs, TourSettings(limits=MotionLimits(linear_speed=float("nan"))))
