"""URArm's stop paths against the fake ur_rtde of test_arm.py: moves and waits give up after
the interface's documented default timeouts and stop the arm; a lost control link alone is
noticed during a move; a move seen running ends when it stops running even if the progress
word comes back to its old idle value. Time is the fake controller's SimClock."""

from __future__ import annotations

import inspect
import math

import numpy as np
import pytest

from armstereo.devices import Arm
from armstereo.errors import (
    ConfigError,
    ConnectionLost,
    EmergencyStop,
    HardwareError,
    MotionTimeout,
    ProtectiveStop,
)
from drivers.ur.arm import REACHED_TOL, STOPJ_DECELERATION, STOPL_DECELERATION, URArm
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
    with pytest.raises(HardwareError, match=r"ended 5\.00 mm / 0\.00 deg from its target "
                                            r"\(allowed 1 mm / 0\.57 deg\)"):
        arm.move_linear(TARGET, 0.05, 0.25, timeout=5.0)
    assert "stopL" in ctl.names()


def test_progress_path_indices_and_a_late_start_are_read_right(arm, ctl, monkeypatch):
    """A controller that reports path indices from 1 while moving, one idle value (-1) before
    and after, and still shows idle for the first polls after the command: the move is over
    only once it has been seen running and is idle again. It ends 5 mm short, so the
    fallback (at the target and steady) cannot hide a misread progress word."""
    real = type(ctl).progress
    polls = {"n": 0}

    def indices(self):
        value = real(self)
        polls["n"] += 1
        if polls["n"] <= 2 or value < 0:  # the operation has not shown up yet, or is over
            return -1
        return polls["n"]

    monkeypatch.setattr(type(ctl), "progress", indices)
    ctl.fault = "short"
    start = ctl.now()
    with pytest.raises(HardwareError, match="ended 5.00 mm"):
        arm.move_linear(TARGET, 0.05, 0.25, timeout=5.0)
    assert ctl.now() - start < 1.0


@pytest.mark.parametrize("moves", [1, 2], ids=["idle -2 to -1", "idle -1 to -2"])
def test_a_move_over_before_the_first_poll_ends_at_once(arm, ctl, moves):
    """Never seen running (it finished between polls): the changed idle value says it is over,
    whichever way the value toggles. Ending 5 mm short, it must be reported as such, not run
    into the timeout."""
    ctl.move_duration = 0.0
    for _ in range(moves - 1):
        arm.move_joints(Q0 + 0.01, 0.5, 1.0, timeout=5.0)
    ctl.fault = "short"
    start = ctl.now()
    with pytest.raises(HardwareError, match="ended 5.00 mm"):
        arm.move_linear(TARGET, 0.05, 0.25, timeout=5.0)
    assert ctl.now() - start < 1.0


def end_off_target(ctl, monkeypatch, offset):
    """The next joint move ends ``offset`` rad off its target on joint 1."""
    real = type(ctl).progress

    def off(self):
        moving = self.motion is not None
        value = real(self)
        if moving and self.motion is None:
            self.q = self.q + np.r_[offset, 0, 0, 0, 0, 0]
        return value

    monkeypatch.setattr(type(ctl), "progress", off)


def test_a_joint_move_within_the_reached_tolerance_is_done(arm, ctl, monkeypatch):
    end_off_target(ctl, monkeypatch, 0.5 * REACHED_TOL[1])
    arm.move_joints(Q0 + 0.1, 0.5, 1.0, timeout=5.0)
    assert "stopJ" not in ctl.names()


def test_a_joint_move_beyond_the_reached_tolerance_is_an_error(arm, ctl, monkeypatch):
    end_off_target(ctl, monkeypatch, 2 * REACHED_TOL[1])
    with pytest.raises(HardwareError, match="from its target"):
        arm.move_joints(Q0 + 0.1, 0.5, 1.0, timeout=5.0)
    assert "stopJ" in ctl.names()


@pytest.mark.parametrize(("move", "stop", "deceleration"), [
    ("linear", "stopL", STOPL_DECELERATION), ("joints", "stopJ", STOPJ_DECELERATION)])
def test_a_failed_move_stops_with_its_own_command_and_deceleration(arm, ctl, move, stop,
                                                                  deceleration):
    ctl.fault = "protective"
    with pytest.raises(ProtectiveStop, match="is in a protective stop"):
        if move == "linear":
            arm.move_linear(TARGET, 0.05, 0.25, timeout=5.0)
        else:
            arm.move_joints(Q0 + 0.1, 0.5, 1.0, timeout=5.0)
    stops = [c for c in ctl.calls if c[0] in ("stopL", "stopJ")]
    assert stops == [(stop, (deceleration,), {})]
    arm.stop()  # a later stop matches the last move too
    assert ctl.calls[-1] == (stop, (deceleration,), {})


def test_an_emergency_stop_is_named_as_such(arm, ctl):
    ctl.fault = "estop"
    with pytest.raises(EmergencyStop, match="is in an emergency stop"):
        arm.move_linear(TARGET, 0.05, 0.25, timeout=5.0)


@pytest.mark.parametrize("n", [5, 7])
def test_joint_targets_of_the_wrong_length_are_refused_before_any_call(arm, ctl, n):
    with pytest.raises(ConfigError, match="6 finite joint angles"):
        arm.move_joints(np.zeros(n), 0.5, 0.5)
    assert ctl.calls == []


def test_a_closed_arm_can_connect_again(arm, ctl):
    arm.close()
    assert not arm.is_connected
    arm.connect()
    assert arm.is_connected


def test_close_never_raises_even_when_the_receive_side_fails(arm, ctl, monkeypatch):
    def broken(self):
        raise RuntimeError("RTDE receive: socket already closed")

    monkeypatch.setattr(type(arm._rr), "disconnect", broken)
    arm.close()
    assert not arm.is_connected


def test_a_move_ending_off_target_says_how_far(arm, ctl, monkeypatch):
    real = type(ctl).progress

    def short_by_12_3_mm(self):
        moving = self.motion is not None
        value = real(self)
        if moving and self.motion is None and self.tcp_pose is not None:
            self.tcp_pose = self.tcp_pose + np.r_[0.0123, 0, 0, 0, 0, 0]
        return value

    monkeypatch.setattr(type(ctl), "progress", short_by_12_3_mm)
    with pytest.raises(HardwareError, match=r"ended 12\.30 mm / 0\.00 deg"):
        arm.move_linear(TARGET, 0.05, 0.25, timeout=5.0)
