"""View tours: every joint move checked as a scan's, one joint speed that keeps flange and camera
under the linear caps, refusals; run through capture_to_file (views recorded from the actual
joints, the arm back at the start; on a fault the arm stops and the views so far are kept)."""

from __future__ import annotations

import numpy as np
import pytest

from armstereo import backends
from armstereo.capture.plan import Workspace
from armstereo.capture.run import model_metadata
from armstereo.capture.session import capture_to_file
from armstereo.capture.view_tour import plan_view_tour, tour_settings
from armstereo.devices import MAX_JOINT_SPEED, MotionLimits
from armstereo.errors import CameraTimeout, ConfigError, PreflightError
from armstereo.recording import Recording
from armstereo.robot.arm_model import ArmModel
from drivers.mock.start_poses import table_start

SLOW = MotionLimits(linear_speed=0.05, linear_acceleration=0.25)


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


def _failed(tour) -> list[str]:
    return [c.name for c in tour.checks if not c.ok]


def test_every_move_is_checked_and_the_tool_stays_under_the_linear_cap(model, views):
    q0, qs = views
    tour = plan_view_tour(model, q0, qs, tour_settings(limits=SLOW, settle_s=0.2))
    assert tour.ok, tour.describe()
    assert [c.name for c in tour.checks] == ["speed caps", "start pose", "joint limits",
                                             "singularity", "workspace", "tool speed"]
    # view 0 is where the arm stands: no move into it; then views 1-3 and back to the start
    assert tour.legs[0] is None
    assert [leg.label for leg in tour.legs[1:]] == ["view 0 -> view 1", "view 1 -> view 2",
                                                   "view 2 -> view 3", "view 3 -> start"]
    lim = tour.settings.limits
    assert lim.joint_speed < SLOW.joint_speed  # the linear cap binds, not the joint cap
    assert lim.joint_speed * tour.lever_m == pytest.approx(SLOW.linear_speed)
    assert lim.joint_acceleration <= SLOW.linear_acceleration / tour.lever_m + 1e-12
    # the lever is real: no sample pair moves flange or camera faster than that
    assert 0.1 < tour.lever_m < 1.0
    steps = tour.steps()
    assert [(s.move, s.view) for s in steps] == [("none", 0), ("joints", 1), ("joints", 2),
                                                 ("joints", 3), ("joints", None)]
    np.testing.assert_array_equal(steps[-1].target, q0)
    expected = sum(leg.duration_s for leg in tour.legs[1:]) + 4 * 0.2
    assert tour.duration_s == pytest.approx(expected)
    text = "\n".join(tour.describe())
    assert "view 3 -> start" in text and "[ok] tool speed" in text


def test_a_faster_linear_cap_moves_the_joints_faster_up_to_their_cap(model, views):
    q0, qs = views
    slow = plan_view_tour(model, q0, qs, tour_settings(limits=SLOW))
    fast = plan_view_tour(model, q0, qs, tour_settings(
        limits=MotionLimits(linear_speed=0.25, linear_acceleration=1.0)))
    assert fast.settings.limits.joint_speed > slow.settings.limits.joint_speed
    assert fast.duration_s < slow.duration_s
    assert fast.settings.limits.joint_speed <= MotionLimits().joint_speed


def test_workspace_and_caps_are_refused_before_anything_moves(model, views):
    q0, qs = views
    cam = model.camera_pose(q0)[:3, 3]
    box = Workspace(tuple(cam - 0.01), tuple(cam + 0.01))  # the flange is outside it
    tour = plan_view_tour(model, q0, qs, tour_settings(workspace=box))
    assert _failed(tour) == ["workspace"]
    with pytest.raises(PreflightError, match="'workspace' failed.*nothing moved"):
        tour.require_ok()
    too_fast = MotionLimits(joint_speed=MAX_JOINT_SPEED * 2)
    assert "speed caps" in _failed(plan_view_tour(model, q0, qs, tour_settings(
        limits=too_fast)))


def test_views_near_a_joint_limit_or_a_singularity_are_refused(model, views):
    q0, qs = views
    near_limit = qs[1].copy()
    near_limit[5] = model.upper[5] - 0.01
    assert "joint limits" in _failed(plan_view_tour(model, q0, [qs[0], near_limit],
                                                    tour_settings()))
    stretched = q0.copy()
    stretched[4] = 0.0  # wrist 2 at zero: wrist singularity
    assert "singularity" in _failed(plan_view_tour(model, q0, [qs[0], stretched],
                                                   tour_settings()))


def test_bad_settings_are_config_errors(model, views):
    q0, qs = views
    with pytest.raises(ConfigError, match="--settle"):
        plan_view_tour(model, q0, qs, tour_settings(settle_s=-1.0))


def _devices(model, q0, **camera):
    arm = backends.build_arm("mock", backends.arm_config("mock", q0=tuple(q0)), model)
    cam = backends.build_camera("mock", backends.camera_config("mock", **camera), model, arm)
    return arm, cam


def test_capture_runs_the_tour_and_returns_to_the_start(model, views, tmp_path):
    q0, qs = views
    tour = plan_view_tour(model, q0, qs[:3], tour_settings(settle_s=0.1))
    arm, cam = _devices(model, q0)
    out = tmp_path / "tour.mcap"
    with arm, cam:
        result = capture_to_file(arm, cam, model, tour, out, model_metadata(model),
                                 progress=None)
        q_end = arm.joint_positions()
    assert result.views == 3 and result.pairs == []
    np.testing.assert_allclose(q_end, q0, atol=1e-12)
    moves = [args for name, args in arm.history if name == "move_joints"]
    assert len(moves) == 3  # views 1 and 2, then home (view 0 is where the arm stands)
    lim = tour.settings.limits
    assert all(m["speed"] == lim.joint_speed and m["acceleration"] == lim.joint_acceleration
               for m in moves)
    rec = Recording.open(out)
    assert [v.index for v in rec.views] == [0, 1, 2]
    for v, q in zip(rec.views, tour.q_views, strict=True):
        np.testing.assert_allclose(v.joint_positions, q, atol=1e-12)
        np.testing.assert_allclose(v.T_base_flange, model.flange_pose(q), atol=1e-12)


def test_a_fault_stops_the_arm_and_keeps_the_views_so_far(model, views, tmp_path):
    q0, qs = views
    tour = plan_view_tour(model, q0, qs[:3], tour_settings(settle_s=0.1))
    arm, cam = _devices(model, q0, faults=("camera-timeout@2",))
    out = tmp_path / "tour.mcap"
    with arm, cam, pytest.raises(CameraTimeout, match=r"1 view\(s\) kept in"):
        capture_to_file(arm, cam, model, tour, out, {}, progress=None)
    assert ("stop", {}) in arm.history
    assert [v.index for v in Recording.open(out).views] == [0]
