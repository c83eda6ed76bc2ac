"""Running a tour on the mock backends: every view recorded from the actual joints, the arm
back at the start; on a fault the arm is told to stop and the views so far are kept."""

from __future__ import annotations

import numpy as np
import pytest

from armstereo import backends
from armstereo.capture.run import model_metadata
from armstereo.capture.tour import TourSettings, plan_tour
from armstereo.capture.tour_run import record_tour
from armstereo.errors import CameraTimeout, PreflightError
from armstereo.kinematics import ArmModel
from armstereo.recording import Recording
from drivers.mock.start_poses import table_start


@pytest.fixture(scope="module")
def model() -> ArmModel:
    return ArmModel.load("ur5e", mount="default_wrist_camera")


FAST = TourSettings(settle_s=0.1)


def _tour(model, settings=FAST):
    q0 = table_start(model)
    qs = [q0, q0 + [0.1, 0, 0, 0, 0, 0.4], q0 + [-0.1, 0.05, -0.05, 0, 0.1, -0.3]]
    return q0, plan_tour(model, q0, qs, settings)


def _devices(model, q0, **camera):
    arm = backends.build_arm("mock", backends.arm_config("mock", q0=tuple(q0)), model)
    cam = backends.build_camera("mock", backends.camera_config("mock", **camera), model, arm)
    return arm, cam


def test_tour_records_every_view_and_returns_to_the_start(model, tmp_path):
    q0, plan = _tour(model)
    arm, cam = _devices(model, q0)
    out = tmp_path / "tour.mcap"
    with arm, cam:
        result = record_tour(arm, cam, model, plan, out, model_metadata(model), progress=None)
        q_end = arm.joint_positions()
    assert result.views == 3
    np.testing.assert_allclose(q_end, q0, atol=1e-12)
    moves = [args for name, args in arm.history if name == "move_joints"]
    assert len(moves) == 3  # view 1, view 2, home (view 0 is where the arm stands)
    for args, planned in zip(moves, plan.moves, strict=True):
        assert args["speed"] == planned.speed and args["acceleration"] == planned.acceleration
    rec = Recording.open(out)
    assert [v.index for v in rec.views] == [0, 1, 2]
    for v, q in zip(rec.views, plan.q_views, strict=True):
        np.testing.assert_allclose(v.joint_positions, q, atol=1e-12)
        np.testing.assert_allclose(v.T_base_flange, model.flange_pose(q), atol=1e-12)


def test_a_fault_stops_the_arm_and_keeps_the_views_so_far(model, tmp_path):
    q0, plan = _tour(model)
    arm, cam = _devices(model, q0, faults=("camera-timeout@2",))
    out = tmp_path / "tour.mcap"
    with arm, cam, pytest.raises(CameraTimeout, match=r"1 view\(s\) kept in"):
        record_tour(arm, cam, model, plan, out, {}, progress=None)
    assert ("stop", {}) in arm.history
    assert [v.index for v in Recording.open(out).views] == [0]


def test_nothing_recorded_leaves_no_file_and_a_refused_plan_no_motion(model, tmp_path):
    q0, plan = _tour(model)
    arm, cam = _devices(model, q0, faults=("camera-timeout@1",))
    out = tmp_path / "tour.mcap"
    with arm, cam, pytest.raises(CameraTimeout, match="no view was recorded"):
        record_tour(arm, cam, model, plan, out, {}, progress=None)
    assert not out.exists()
    _, refused = _tour(model, TourSettings(max_joint_travel=0.05))
    arm, cam = _devices(model, q0)
    with arm, cam, pytest.raises(PreflightError):
        record_tour(arm, cam, model, refused, out, {}, progress=None)
    assert not out.exists() and not any(n.startswith("move") for n, _ in arm.history)
