"""URArm against a real UR controller (``pytest -m hardware --ur-host IP``).

Reading tests only connect and read. The motion test moves the flange 10 mm up and back at
20 mm/s and runs only with ``--ur-allow-motion`` as well: clear the workspace and keep a hand on
the e-stop. ``--ur-model`` picks the robot model (default ur5e).
"""

from __future__ import annotations

import numpy as np
import pytest

from armstereo.devices import ArmState

pytestmark = pytest.mark.hardware

MOTION_STEP_M = 0.01
MOTION_SPEED = 0.02          # m/s
MOTION_ACCELERATION = 0.1    # m/s^2


@pytest.fixture
def arm(ur_host, request):
    # Imported here so collecting this file needs neither the kinematics nor a robot.
    from armstereo.robot.arm_model import ArmModel
    from drivers.ur.arm import URArm

    model = ArmModel.load(request.config.getoption("--ur-model", default="ur5e"))
    ur = URArm(ur_host, model)
    ur.connect()
    yield ur
    ur.close()


def test_connect_reads_fresh_joints_and_status(arm):
    st = arm.status()
    assert st.state is ArmState.NORMAL, st.detail
    q1 = arm.joint_positions()
    t1 = arm.last_controller_timestamp
    q2 = arm.joint_positions()
    assert q1.shape == (6,) and np.all(np.isfinite(q1))
    assert arm.last_controller_timestamp > t1  # every reading comes from a newer package
    assert np.max(np.abs(q2 - q1)) < 1e-3     # standing still
    # Connect checked FK against the controller; factory calibration stays within a few mm.
    assert arm.fk_mismatch[0] < 0.005


def test_controller_flange_pose_matches_model_fk(arm):
    arm.wait_until_steady(timeout=5.0)
    T_fk = arm.model.flange_pose(arm.joint_positions())
    T_ctrl = arm.controller_flange_pose()
    assert np.linalg.norm(T_ctrl[:3, 3] - T_fk[:3, 3]) < 0.005
    assert np.allclose(T_ctrl[:3, :3], T_fk[:3, :3], atol=0.01)


def test_small_guarded_linear_move_up_and_back(arm, request):
    if not request.config.getoption("--ur-allow-motion", default=False):
        pytest.skip("moves the arm 10 mm: pass --ur-allow-motion (workspace clear, e-stop at hand)")
    arm.require_ok()
    arm.wait_until_steady(timeout=5.0)
    q0 = arm.joint_positions()
    T0 = arm.model.flange_pose(q0)
    T1 = T0.copy()
    T1[2, 3] += MOTION_STEP_M
    try:
        arm.move_linear(T1, MOTION_SPEED, MOTION_ACCELERATION, timeout=10.0)
        arm.wait_until_steady(timeout=5.0)
        moved = arm.model.flange_pose(arm.joint_positions())[:3, 3] - T0[:3, 3]
        np.testing.assert_allclose(moved, [0, 0, MOTION_STEP_M], atol=5e-4)
    finally:
        arm.move_linear(T0, MOTION_SPEED, MOTION_ACCELERATION, timeout=10.0)
        arm.wait_until_steady(timeout=5.0)
    back = arm.model.flange_pose(arm.joint_positions())[:3, 3]
    np.testing.assert_allclose(back, T0[:3, 3], atol=5e-4)
