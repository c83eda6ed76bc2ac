"""The mock arm's stop path: a stop never raises, is recorded, and a stop that cannot reach the
arm (no link) is reported as such among the simulation's own events."""

from __future__ import annotations

import pytest

from armstereo.errors import ConnectionLost
from armstereo.kinematics import ArmModel
from drivers.mock.arm import MockArm
from drivers.mock.faults import FaultPlan
from drivers.mock.start_poses import table_start

UNREACHED = "stop requested without a link"


@pytest.fixture(scope="module")
def model() -> ArmModel:
    return ArmModel.load("ur5e", mount="default_wrist_camera")


def test_a_stop_on_a_live_link_reaches_the_arm(model):
    arm = MockArm(model, table_start(model))
    arm.connect()
    arm.stop()
    assert arm.history[-1][0] == "stop" and UNREACHED not in arm.events


@pytest.mark.parametrize("how", ["never connected", "closed", "link lost"])
def test_a_stop_without_a_link_never_raises_and_says_so(model, how):
    arm = MockArm(model, table_start(model), faults=FaultPlan.parse(["disconnect@1"]))
    if how != "never connected":
        arm.connect()
    if how == "closed":
        arm.close()
    if how == "link lost":
        T = model.flange_pose(arm.joint_positions())
        T[2, 3] += 0.01
        with pytest.raises(ConnectionLost):
            arm.move_linear(T, 0.05, 0.25)
    arm.stop()
    assert arm.history[-1][0] == "stop" and arm.events[-1] == UNREACHED


def test_a_closed_arm_is_disconnected_and_can_connect_again(model):
    arm = MockArm(model, table_start(model))
    arm.connect()
    arm.close()
    assert not arm.is_connected and arm.status().state.value == "disconnected"
    arm.connect()
    assert arm.is_connected and arm.status().ok


def test_a_stuck_move_gives_up_exactly_at_the_callers_timeout(model):
    """Also when the timeout is shorter than the time to the point where the move sticks."""
    from armstereo.errors import MotionTimeout

    arm = MockArm(model, table_start(model), faults=FaultPlan.parse(["stuck-move@1"]))
    arm.connect()
    T = model.flange_pose(arm.joint_positions())
    T[0, 3] += 0.1  # 2.2 s at 0.05 m/s; it would stick at 1.1 s
    start = arm.clock.now()
    with pytest.raises(MotionTimeout):
        arm.move_linear(T, 0.05, 0.25, timeout=0.5)
    assert arm.clock.now() - start == pytest.approx(0.5, abs=1e-9)
