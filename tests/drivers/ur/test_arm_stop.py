"""URArm's stop paths against the fake ur_rtde of test_arm.py: moves and waits give up after
the interface's documented default timeouts and stop the arm; a lost control link alone is
noticed during a move; a move seen running ends when it stops running even if the progress
word comes back to its old idle value. Time is the fake controller's SimClock."""

from __future__ import annotations

import inspect
import math

import pytest

from armstereo.devices import Arm
from armstereo.errors import ConnectionLost, HardwareError, MotionTimeout
from drivers.ur.arm import URArm
from tests.drivers.ur import test_arm as fake
from tests.drivers.ur.test_arm import Q0, FakeModel

ctl = fake.ctl  # the fake controller and the connected arm of test_arm.py (fixtures)
arm = fake.arm
TARGET = FakeModel().flange_pose(Q0 + 0.05)


def default(method: str) -> float:
    return inspect.signature(getattr(Arm, method)).parameters["timeout"].default


@pytest.mark.parametrize("method", ["move_linear", "move_joints", "wait_until_steady"])
def test_the_ur_arm_keeps_the_interfaces_default_timeouts(method):
    assert inspect.signature(getattr(URArm, method)).parameters["timeout"].default \
        == default(method)


def test_a_move_that_never_finishes_gives_up_after_the_default_timeout(arm, ctl):
    ctl.fault = "never_finish"
    start = ctl.now()
    with pytest.raises(MotionTimeout, match=f"within {default('move_linear'):g} s"):
        arm.move_linear(TARGET, 0.05, 0.25)
    waited = ctl.now() - start
    assert default("move_linear") < waited < default("move_linear") + 2 * arm.poll_interval
    assert ctl.names()[-1] == "stopL"


def test_waiting_for_rest_gives_up_after_the_default_timeout(arm, ctl):
    ctl.start("J", Q0 + 0.1)
    ctl.motion = ("J", Q0 + 0.1, math.inf)
    start = ctl.now()
    with pytest.raises(MotionTimeout):
        arm.wait_until_steady()
    waited = ctl.now() - start
    assert default("wait_until_steady") < waited < default("wait_until_steady") + 2 * \
        arm.poll_interval
    assert "stopL" in ctl.names()


def test_a_lost_control_link_alone_ends_the_move_with_a_stop(arm, ctl, monkeypatch):
    """RTDE data keeps coming but the control interface says it is disconnected."""
    control = type(arm._ch.target)
    monkeypatch.setattr(control, "isConnected", lambda self: False)
    with pytest.raises(ConnectionLost, match="control connection"):
        arm.move_linear(TARGET, 0.05, 0.25, timeout=5.0)
    assert "stopL" in ctl.names()


def test_a_move_seen_running_ends_when_it_stops_even_without_a_new_idle_value(arm, ctl,
                                                                              monkeypatch):
    """Some controllers report the same idle progress value before and after an operation;
    a move that was seen running is over once it is idle again. Here it ends 5 mm short:
    that must be reported as such, at once, not run into the timeout."""
    ctl.fault = "short"
    real = type(ctl).progress

    def same_idle_value(self):
        value = real(self)
        return -2 if value < 0 else value

    monkeypatch.setattr(type(ctl), "progress", same_idle_value)
    with pytest.raises(HardwareError, match=r"ended 5\.00 mm .* \(allowed 1 mm"):
        arm.move_linear(TARGET, 0.05, 0.25, timeout=5.0)
    assert "stopL" in ctl.names()
