"""URArm against fake ur_rtde modules (call order, error mapping, stop on error) and the RTDE
probe against a scripted socket server. No robot, no real ur_rtde connection; time is a
SimClock, so polling loops and timeouts cost no wall time."""

from __future__ import annotations

import dataclasses
import logging
import math
import socket
import struct
import sys
import threading
import time
import types

import numpy as np
import pytest

from armstereo.clock import SimClock
from armstereo.devices import MAX_JOINT_SPEED, MAX_LINEAR_ACCELERATION, MAX_LINEAR_SPEED, ArmState
from armstereo.errors import (
    ConfigError,
    ConnectionFailed,
    ConnectionLost,
    EmergencyStop,
    HardwareError,
    JointLimitError,
    MotionTimeout,
    NotConnected,
    ProtectiveStop,
)
from armstereo.robot.dh import nominal_table
from armstereo.transforms import make_T, rot_x, rot_y, rot_z, ur_pose_from_T
from drivers.ur import arm as arm_module
from drivers.ur import primary, probe
from drivers.ur.arm import URArm
from drivers.ur.channel import ControlChannel
from drivers.ur.connect import RECEIVE_VARIABLES
from drivers.ur.probe import ControllerInfo

HOST = "192.0.2.10"  # TEST-NET-1: never a real controller
PERIOD = 0.002       # fake RTDE period (500 Hz)
Q0 = np.array([0.1, -0.2, 0.3, -0.4, 0.5, -0.6])
BIT_PROTECTIVE, BIT_ESTOP = 1 << 2, 1 << 7


class FakeModel:
    """A toy ArmModel: FK is an arbitrary smooth map of q; limits |q| <= 2 pi."""

    name = "fake"

    def flange_pose(self, q):
        q = np.asarray(q, dtype=float)
        R = rot_z(q[0]) @ rot_y(q[1]) @ rot_x(q[5])
        return make_T(R, [0.4 + 0.1 * q[2], 0.1 * q[3], 0.3 + 0.1 * q[4]])

    def check_limits(self, q, margin=0.0):
        bad = np.flatnonzero(np.abs(q) > 2 * np.pi - margin)
        if bad.size:
            raise JointLimitError(f"joint {bad[0]} at {q[bad[0]]:.3f} rad outside +-2pi")


class FakeController:
    """State of a fake UR controller shared by the fake receive/control/dashboard objects.

    Time is the SimClock: the RTDE timestamp advances in PERIOD steps as the arm sleeps. An
    asynchronous move runs for ``move_duration`` s; ``fault`` misbehaves once a move runs:
    "protective", "estop", "disconnect", "never_finish", "short" (ends 5 mm off),
    "stuck_progress" (progress word never changes).
    """

    def __init__(self, clock: SimClock):
        self.clock, self.t0 = clock, clock.now_ns()
        self.calls: list[tuple[str, tuple, dict]] = []
        self.q = Q0.copy()
        self.tcp_pose: np.ndarray | None = None  # set by moveL; else FK of q
        self.tcp_offset_error = np.zeros(6)      # controller FK minus model FK
        self.safety_bits, self.safety_mode, self.robot_mode, self.runtime_state = 1, 1, 7, 1
        self.link_up, self.frozen_at = True, None
        self.op_id, self.motion, self.move_duration = 0, None, 0.05
        self.fault: str | None = None
        self.refuse_moves = False
        self.stop_behaviour = "ok"           # "ok", "raise", "hang"
        self.release = threading.Event()
        self.control_error: Exception | None = None
        self.receive_error: Exception | None = None
        self.unlock_error: Exception | None = None

    # -- bookkeeping
    def log(self, name, *args, **kwargs):
        self.calls.append((name, args, kwargs))

    def names(self) -> list[str]:
        return [c[0] for c in self.calls]

    def call(self, name):
        return next(c for c in self.calls if c[0] == name)

    def now(self) -> float:
        return (self.clock.now_ns() - self.t0) * 1e-9

    def timestamp(self) -> float:
        t = self.now() if self.frozen_at is None else self.frozen_at
        return math.floor(t / PERIOD + 1e-9) * PERIOD

    def pose6(self) -> np.ndarray:
        if self.tcp_pose is not None:
            return self.tcp_pose.copy()
        return ur_pose_from_T(FakeModel().flange_pose(self.q)) + self.tcp_offset_error

    # -- motion
    def start(self, kind, target):
        if self.refuse_moves or self.runtime_state != 2:
            return False
        self.op_id += 1
        end = math.inf if self.fault == "never_finish" else self.now() + self.move_duration
        self.motion = (kind, np.asarray(target, dtype=float), end)
        return True

    def progress(self) -> int:
        idle = (self.op_id % 2) - 2
        if self.motion is None:
            return -2 if self.fault == "stuck_progress" else idle
        if self.fault in ("protective", "estop", "disconnect"):
            self._trip()
            return idle
        kind, target, end = self.motion
        if self.now() < end:
            return -2 if self.fault == "stuck_progress" else 0
        self.motion = None
        if kind == "L":
            self.tcp_pose = target + ([0.005, 0, 0, 0, 0, 0] if self.fault == "short" else 0)
        else:
            self.q, self.tcp_pose = target, None
        return -2 if self.fault == "stuck_progress" else idle

    def _trip(self):
        self.motion = None
        if self.fault == "protective":
            self.safety_bits, self.safety_mode, self.runtime_state = BIT_PROTECTIVE, 3, 1
        elif self.fault == "estop":
            self.safety_bits, self.safety_mode, self.robot_mode = BIT_ESTOP, 7, 5
        else:
            self.link_up = False

    # -- the fake modules
    def install(self, monkeypatch):
        ctl = self
        modules = {
            "rtde_receive": {"RTDEReceiveInterface": type("RTDEReceiveInterface", (FakeReceive,),
                                                         {"ctl": ctl})},
            "rtde_control": {"RTDEControlInterface": type("RTDEControlInterface", (FakeControl,),
                                                         {"ctl": ctl})},
            "dashboard_client": {"DashboardClient": type("DashboardClient", (FakeDashboard,),
                                                         {"ctl": ctl})},
        }
        for name, attrs in modules.items():
            module = types.ModuleType(name)
            for key, value in attrs.items():
                setattr(module, key, value)
            monkeypatch.setitem(sys.modules, name, module)

        def fake_check(host, timeout):
            ctl.log("check", host, timeout)
            return ControllerInfo(host, (5, 12, 0, 0))

        monkeypatch.setattr(arm_module, "check_controller", fake_check)
        # No primary stream here (and no traffic to HOST): the table is "not read".
        monkeypatch.setattr(arm_module, "read_arm_kinematics",
                            lambda host, model, timeout: primary._nominal(
                                model, None, ["no primary stream in this test"]))
        monkeypatch.setattr(arm_module, "check_port",
                            lambda host, port, timeout, what: ctl.log("check_port", host, port))


class FakeReceive:
    ctl: FakeController

    def __init__(self, hostname, frequency=-1.0, variables=(), verbose=False,
                 use_upper_range_registers=False, rt_priority=0):
        self.ctl.log("receive", hostname, frequency, tuple(variables), use_upper_range_registers)
        if self.ctl.receive_error is not None:
            raise self.ctl.receive_error

    def getTimestamp(self):
        t = self.ctl.timestamp()
        self.ctl.log("getTimestamp", t)
        return t

    def getActualQ(self):
        self.ctl.log("getActualQ", self.ctl.timestamp())
        return list(self.ctl.q)

    def getActualTCPPose(self):
        return list(self.ctl.pose6())

    def isConnected(self):
        return self.ctl.link_up

    def getSafetyStatusBits(self):
        return self.ctl.safety_bits

    def getSafetyMode(self):
        return self.ctl.safety_mode

    def getRobotMode(self):
        return self.ctl.robot_mode

    def getRuntimeState(self):
        return self.ctl.runtime_state

    def getTargetSpeedFraction(self):
        return 0.3

    def disconnect(self):
        self.ctl.log("receive.disconnect")


class FakeControl:
    ctl: FakeController
    FLAG_UPLOAD_SCRIPT = 0x01
    FLAG_UPPER_RANGE_REGISTERS = 0x08

    def __init__(self, hostname, frequency=-1.0, flags=1, ur_cap_port=50002, rt_priority=0):
        self.ctl.log("control", hostname, frequency, flags)
        if self.ctl.control_error is not None:
            raise self.ctl.control_error
        self.ctl.runtime_state = 2

    def setTcp(self, pose):
        self.ctl.log("setTcp", list(pose))
        return True

    def moveL(self, pose, speed=0.25, acceleration=1.2, asynchronous=False):
        self.ctl.log("moveL", list(pose), speed, acceleration, asynchronous=asynchronous)
        return self.ctl.start("L", pose)

    def moveJ(self, q, speed=1.05, acceleration=1.4, asynchronous=False):
        self.ctl.log("moveJ", list(q), speed, acceleration, asynchronous=asynchronous)
        return self.ctl.start("J", q)

    def _stop(self, name, a):
        self.ctl.log(name, a)
        if self.ctl.stop_behaviour == "raise":
            raise RuntimeError("RTDEControlInterface: RTDE control script is not running!")
        if self.ctl.stop_behaviour == "hang":
            self.ctl.release.wait(5.0)
        self.ctl.motion = None

    def stopL(self, a=10.0, asynchronous=False):
        self._stop("stopL", a)

    def stopJ(self, a=2.0, asynchronous=False):
        self._stop("stopJ", a)

    def getAsyncOperationProgress(self):
        return self.ctl.progress()

    def isSteady(self):
        self.ctl.log("isSteady")
        self.ctl.progress()  # lets a finished motion end
        return self.ctl.motion is None

    def isConnected(self):
        return self.ctl.link_up

    def stopScript(self):
        self.ctl.log("stopScript")
        self.ctl.runtime_state = 1

    def reuploadScript(self):
        self.ctl.log("reuploadScript")
        self.ctl.runtime_state = 2
        return True

    def disconnect(self):
        self.ctl.log("control.disconnect")


class FakeDashboard:
    ctl: FakeController

    def __init__(self, hostname, port=29999, verbose=False):
        self.ctl.log("dashboard", hostname)

    def connect(self, timeout_ms=2000):
        self.ctl.log("dashboard.connect", timeout_ms)

    def unlockProtectiveStop(self):
        self.ctl.log("unlockProtectiveStop")
        if self.ctl.unlock_error is not None:
            raise self.ctl.unlock_error
        self.ctl.safety_bits, self.ctl.safety_mode = 1, 1

    def closeSafetyPopup(self):
        self.ctl.log("closeSafetyPopup")

    def disconnect(self):
        self.ctl.log("dashboard.disconnect")


@pytest.fixture
def ctl(monkeypatch) -> FakeController:
    controller = FakeController(SimClock())
    controller.install(monkeypatch)
    return controller


@pytest.fixture
def arm(ctl):
    ur = URArm(HOST, FakeModel(), clock=ctl.clock)
    ur.connect()
    ctl.calls.clear()
    yield ur
    ctl.release.set()
    ur.close()


def _closed_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


# ------------------------------------------------------------------------------------- connect
def test_connect_order_and_arguments(ctl):
    ur = URArm(HOST, FakeModel(), clock=ctl.clock)
    ur.connect()
    main = [n for n in ctl.names() if n in ("check", "receive", "control", "setTcp")]
    assert main == ["check", "receive", "control", "setTcp"]
    _, (host, freq, variables, upper), _ = ctl.call("receive")
    assert (host, freq, variables, upper) == (HOST, -1.0, RECEIVE_VARIABLES, False)
    assert ctl.call("control")[1] == (HOST, -1.0, 0x01)
    assert ctl.call("setTcp")[1] == ([0.0] * 6,)
    assert ur.is_connected and ur.status().state is ArmState.NORMAL
    assert ur.controller.series == "e-Series"
    assert ur.fk_mismatch[0] < 1e-9
    ur.close()


def test_upper_range_registers_reach_both_interfaces(ctl):
    ur = URArm(HOST, FakeModel(), upper_range_registers=True, frequency=125.0, clock=ctl.clock)
    ur.connect()
    assert ctl.call("receive")[1][1:] == (125.0, RECEIVE_VARIABLES, True)
    assert ctl.call("control")[1] == (HOST, 125.0, 0x01 | 0x08)
    ur.close()


def test_nothing_listening_fails_fast_naming_host(ctl, monkeypatch):
    monkeypatch.setattr(arm_module, "check_controller", probe.check_controller)  # the real one
    monkeypatch.setattr(probe, "RTDE_PORT", _closed_port())
    ur = URArm("127.0.0.1", FakeModel(), clock=ctl.clock)
    start = time.monotonic()
    with pytest.raises(ConnectionFailed, match=r"cannot reach UR controller at 127\.0\.0\.1"):
        ur.connect()
    assert time.monotonic() - start < 5.0
    assert "receive" not in ctl.names()
    assert not ur.is_connected


@pytest.mark.parametrize("text, expected", [
    ("One of the RTDE input registers are already in use! Currently you must disable the "
     "EtherNet/IP adapter", "upper_range_registers=True"),
    ("ur_rtde: Please enable remote control on the robot!", "Remote Control"),
    ("ur_rtde: Failed to start control script, before timeout of 5 seconds",
     "power the arm on"),
    ("Timeout connecting to UR dashboard server.", "29999"),
    ("something new", "opening the RTDE control interface failed: something new"),
])
def test_control_constructor_error_maps_and_closes_receive(ctl, text, expected):
    ctl.control_error = RuntimeError(text)
    ur = URArm(HOST, FakeModel(), clock=ctl.clock)
    with pytest.raises(ConnectionFailed, match=HOST) as info:
        ur.connect()
    assert expected in str(info.value) and "\n" not in str(info.value)
    assert "receive.disconnect" in ctl.names()
    assert ur.status().state is ArmState.DISCONNECTED


def test_receive_constructor_error_maps(ctl):
    ctl.receive_error = RuntimeError(f"Error: Could not connect to: {HOST} at 30004, verify the IP")
    with pytest.raises(ConnectionFailed, match=f"cannot reach UR controller at {HOST}:30004"):
        URArm(HOST, FakeModel(), clock=ctl.clock).connect()
    assert "control" not in ctl.names()


@pytest.mark.parametrize("bits, safety, robot, error, text", [
    (BIT_PROTECTIVE, 3, 7, ProtectiveStop, "protective stop"),
    (BIT_ESTOP, 7, 5, EmergencyStop, "emergency stop"),
    (1, 1, 3, ConnectionFailed, "POWER_OFF"),
])
def test_stopped_controller_refused_before_script_upload(ctl, bits, safety, robot, error, text):
    ctl.safety_bits, ctl.safety_mode, ctl.robot_mode = bits, safety, robot
    with pytest.raises(error, match=text):
        URArm(HOST, FakeModel(), clock=ctl.clock).connect()
    assert "control" not in ctl.names()
    assert "receive.disconnect" in ctl.names()


def test_fk_cross_check_warns_then_refuses_wrong_model(ctl, caplog):
    ctl.tcp_offset_error = np.array([0.004, 0, 0, 0, 0, 0])
    with caplog.at_level(logging.WARNING, logger="drivers.ur.arm"):
        ur = URArm(HOST, FakeModel(), clock=ctl.clock)
        ur.connect()
    assert "4.00 mm" in caplog.text and ur.fk_mismatch[0] == pytest.approx(0.004)
    ur.close()
    ctl.calls.clear()
    ctl.tcp_offset_error = np.array([0.0, 0.05, 0, 0, 0, 0])
    with pytest.raises(ConfigError, match="50.00 mm"):
        URArm(HOST, FakeModel(), clock=ctl.clock).connect()
    assert {"stopScript", "control.disconnect", "receive.disconnect"} <= set(ctl.names())


@pytest.mark.parametrize(("offset_m", "warned"), [(5e-5, False), (2e-4, True)])
def test_fk_cross_check_is_tight_once_the_controllers_table_was_read(ctl, monkeypatch, caplog,
                                                                    offset_m, warned):
    """With the controller's own table, 0.2 mm between its pose and our FK means the table is
    not this arm's (the nominal-model tolerance is 1 mm)."""
    table = dataclasses.replace(nominal_table("ur5e"), source="controller",
                                calibration_status=2)
    read = primary.ArmKinematics(table, None, ())
    monkeypatch.setattr(arm_module, "read_arm_kinematics", lambda host, model, timeout: read)
    monkeypatch.setattr("armstereo.robot.arm_model.ArmModel.from_dh",
                        classmethod(lambda cls, table, mount=None: FakeModel()))
    ctl.tcp_offset_error = np.array([offset_m, 0, 0, 0, 0, 0])
    with caplog.at_level(logging.WARNING, logger="drivers.ur.arm"):
        ur = URArm(HOST, FakeModel(), clock=ctl.clock)
        ur.connect()
    assert ur.kinematics.calibrated and isinstance(ur.model, FakeModel)
    assert ("not this arm's" in caplog.text) is warned
    ur.close()


def test_missing_ur_rtde_gives_install_hint(ctl, monkeypatch):
    monkeypatch.setitem(sys.modules, "rtde_control", None)
    with pytest.raises(ConfigError, match="pip install ur-rtde"):
        URArm(HOST, FakeModel(), clock=ctl.clock).connect()


@pytest.mark.parametrize("host", ["", "  ", "192.168.1.5:30004", "http://192.168.1.5", 5])
def test_bad_host_is_a_config_error(host):
    with pytest.raises(ConfigError):
        URArm(host, FakeModel())


# -------------------------------------------------------------------------------------- motion
def test_move_linear_sends_async_movel_with_ur_pose(arm, ctl):
    T = make_T(rot_x(np.pi / 2), [0.3, -0.2, 0.4])
    arm.move_linear(T, 0.05, 0.25, timeout=5.0)
    _, (pose, speed, accel), kwargs = ctl.call("moveL")
    np.testing.assert_allclose(pose, [0.3, -0.2, 0.4, np.pi / 2, 0, 0], atol=1e-12)
    assert (speed, accel, kwargs) == (0.05, 0.25, {"asynchronous": True})
    assert "stopL" not in ctl.names()
    np.testing.assert_allclose(arm.controller_flange_pose(), T, atol=1e-12)


def test_move_joints_sends_async_movej_and_ends_at_target(arm, ctl):
    q = Q0 + 0.1
    arm.move_joints(q, 0.5, 1.0, timeout=5.0)
    _, (target, speed, accel), kwargs = ctl.call("moveJ")
    np.testing.assert_allclose(target, q)
    assert (speed, accel, kwargs) == (0.5, 1.0, {"asynchronous": True})
    np.testing.assert_allclose(arm.joint_positions(), q)


@pytest.mark.parametrize("call", [
    lambda a: a.move_linear(np.eye(4), MAX_LINEAR_SPEED * 1.01, 0.1),
    lambda a: a.move_linear(np.eye(4), 0.05, MAX_LINEAR_ACCELERATION + 0.1),
    lambda a: a.move_linear(np.eye(4), -0.05, 0.1),
    lambda a: a.move_linear(np.eye(4), float("nan"), 0.1),
    lambda a: a.move_joints(Q0, MAX_JOINT_SPEED + 0.5, 0.5),
    lambda a: a.move_linear(np.diag([1.0, 1.0, 2.0, 1.0]), 0.05, 0.1),
    lambda a: a.move_joints(Q0[:5], 0.5, 0.5),
])
def test_bad_move_arguments_refused_before_any_call(arm, ctl, call):
    with pytest.raises(ConfigError):
        call(arm)
    assert ctl.calls == []


def test_joint_limits_refused_before_any_call(arm, ctl):
    with pytest.raises(JointLimitError):
        arm.move_joints(np.r_[Q0[:5], 7.0], 0.5, 0.5)
    assert ctl.calls == []


@pytest.mark.parametrize("fault, error, stop_behaviour", [
    ("protective", ProtectiveStop, "raise"),
    ("estop", EmergencyStop, "ok"),
    ("disconnect", ConnectionLost, "raise"),
])
def test_fault_during_move_stops_then_raises(arm, ctl, fault, error, stop_behaviour):
    ctl.fault, ctl.stop_behaviour = fault, stop_behaviour
    with pytest.raises(error, match=f"{HOST}.*during moveL"):
        arm.move_linear(FakeModel().flange_pose(Q0 + 0.05), 0.05, 0.25, timeout=5.0)
    names = ctl.names()
    assert "stopL" in names and names.index("stopL") > names.index("moveL")
    assert arm.status().state is not ArmState.NORMAL


def test_disconnect_with_hanging_stop_still_raises_connection_lost(arm, ctl):
    ctl.fault, ctl.stop_behaviour = "disconnect", "hang"
    arm.stop_timeout = 0.05
    with pytest.raises(ConnectionLost):
        arm.move_joints(Q0 + 0.1, 0.5, 1.0, timeout=5.0)
    assert "stopJ" in ctl.names()
    arm.stop()  # the control interface is still blocked: must neither raise nor hang
    ctl.release.set()


def test_move_that_never_finishes_times_out_and_stops(arm, ctl):
    ctl.fault = "never_finish"
    with pytest.raises(MotionTimeout, match=r"did not finish within 0\.2 s \(speed slider at 30"):
        arm.move_linear(FakeModel().flange_pose(Q0 + 0.05), 0.05, 0.25, timeout=0.2)
    assert ctl.names().count("stopL") == 1


def test_move_ending_off_target_is_an_error(arm, ctl):
    ctl.fault = "short"
    with pytest.raises(HardwareError, match="ended 5.00 mm"):
        arm.move_linear(FakeModel().flange_pose(Q0 + 0.05), 0.05, 0.25, timeout=5.0)
    assert "stopL" in ctl.names()


def test_stuck_progress_word_falls_back_to_target_and_steady(arm, ctl):
    ctl.fault = "stuck_progress"
    T = FakeModel().flange_pose(Q0 + 0.05)
    arm.move_linear(T, 0.05, 0.25, timeout=5.0)
    assert "isSteady" in ctl.names() and "stopL" not in ctl.names()


def test_refused_move_says_why(arm, ctl):
    ctl.runtime_state = 1
    with pytest.raises(HardwareError, match="control script is not running"):
        arm.move_joints(Q0 + 0.1, 0.5, 1.0)
    assert "stopJ" in ctl.names()


def test_wait_until_steady_times_out_and_stops(arm, ctl):
    ctl.start("J", Q0 + 0.1)
    ctl.motion = ("J", Q0 + 0.1, math.inf)
    with pytest.raises(MotionTimeout, match="not steady within 0.1 s"):
        arm.wait_until_steady(timeout=0.1)
    assert "stopL" in ctl.names()


def test_wait_until_steady_returns_once_motion_ended(arm, ctl):
    ctl.start("J", Q0 + 0.1)
    arm.wait_until_steady(timeout=1.0)
    assert ctl.motion is None and "stopL" not in ctl.names()


# ------------------------------------------------------------------------------------- reading
def test_joint_positions_wait_for_two_fresh_packages(arm, ctl):
    t_call = ctl.timestamp()
    q = arm.joint_positions()
    reads = [c for c in ctl.calls if c[0] == "getActualQ"]
    assert len(reads) == 1 and reads[0][1][0] >= t_call + 2 * PERIOD - 1e-12
    assert arm.last_controller_timestamp == pytest.approx(reads[0][1][0])
    np.testing.assert_allclose(q, Q0)


def test_joint_positions_without_new_data_is_connection_lost(arm, ctl):
    ctl.frozen_at = ctl.now()
    with pytest.raises(ConnectionLost, match="no new RTDE data"):
        arm.joint_positions()
    ctl.frozen_at, ctl.link_up = None, False
    with pytest.raises(ConnectionLost, match=HOST):
        arm.joint_positions()


@pytest.mark.parametrize("bits, safety, robot, state, words", [
    (1, 1, 7, ArmState.NORMAL, "RUNNING"),
    (BIT_PROTECTIVE, 3, 7, ArmState.PROTECTIVE_STOP, "PROTECTIVE_STOP (3)"),
    (1 << 4, 5, 7, ArmState.PROTECTIVE_STOP, "SAFEGUARD_STOP"),
    (BIT_ESTOP | 1 << 6, 7, 5, ArmState.EMERGENCY_STOP, "ROBOT_EMERGENCY_STOP"),
    (1 << 9, 9, 7, ArmState.EMERGENCY_STOP, "FAULT"),
    (1, 1, 3, ArmState.PROTECTIVE_STOP, "POWER_OFF"),
])
def test_status_maps_controller_state(arm, ctl, bits, safety, robot, state, words):
    ctl.safety_bits, ctl.safety_mode, ctl.robot_mode = bits, safety, robot
    st = arm.status()
    assert st.state is state and words in st.detail
    ctl.link_up = False
    assert arm.status().state is ArmState.DISCONNECTED


def test_require_ok_raises_protective_stop(arm, ctl):
    ctl.safety_bits, ctl.safety_mode = BIT_PROTECTIVE, 3
    with pytest.raises(ProtectiveStop, match=HOST):
        arm.require_ok()


# ----------------------------------------------------------------------------------- lifecycle
def test_close_is_idempotent_and_stops_the_script(arm, ctl):
    arm.close()
    arm.close()
    names = ctl.names()
    assert names.count("stopScript") == 1
    assert names.count("control.disconnect") == 1 and names.count("receive.disconnect") == 1
    assert names.index("stopL") < names.index("stopScript") < names.index("control.disconnect")
    assert not arm.is_connected and arm.status().state is ArmState.DISCONNECTED
    with pytest.raises(NotConnected, match="not connected"):
        arm.joint_positions()
    arm.stop()  # nothing to stop, must not raise


def test_connect_twice_is_refused(arm):
    with pytest.raises(NotConnected, match="already connected"):
        arm.connect()


def test_recover_protective_stop_unlocks_then_restarts_script(arm, ctl):
    ctl.fault = "protective"
    with pytest.raises(ProtectiveStop):
        arm.move_linear(FakeModel().flange_pose(Q0 + 0.05), 0.05, 0.25)
    ctl.calls.clear()
    arm.recover_protective_stop(timeout=1.0)
    names = ctl.names()
    assert names.index("unlockProtectiveStop") < names.index("reuploadScript") < \
        names.index("setTcp")
    assert "dashboard.disconnect" in names and arm.status().ok


def test_recover_protective_stop_gives_up_after_timeout(arm, ctl):
    ctl.safety_bits, ctl.safety_mode, ctl.runtime_state = BIT_PROTECTIVE, 3, 1
    ctl.unlock_error = RuntimeError("Protective stop cannot be released until 5 seconds after")
    with pytest.raises(ProtectiveStop, match="within 1 s"):
        arm.recover_protective_stop(timeout=1.0)
    assert ctl.names().count("unlockProtectiveStop") > 1
    assert "dashboard.disconnect" in ctl.names()


def test_recover_is_a_no_op_when_not_stopped(arm, ctl):
    arm.recover_protective_stop()
    assert "unlockProtectiveStop" not in ctl.names()


# ------------------------------------------------------------------------------------- channel
def test_channel_deadline_then_recovers_when_the_call_returns():
    gate = threading.Event()

    class Target:
        def slow(self):
            gate.wait(5.0)
            return "late"

        def fast(self):
            return "ok"

        def broken(self):
            raise RuntimeError("boom\nsecond line")

    ch = ControlChannel(Target(), HOST)
    with pytest.raises(ConnectionLost, match="slow did not return within 0.05 s"):
        ch.call("slow", timeout=0.05)
    with pytest.raises(ConnectionLost, match="earlier slow call"):
        ch.call("fast", timeout=1.0)
    gate.set()
    deadline = time.monotonic() + 2.0
    while ch.stuck and time.monotonic() < deadline:
        time.sleep(0.001)
    assert ch.call("fast", timeout=1.0) == "ok"
    with pytest.raises(HardwareError, match="broken failed: boom second line"):
        ch.call("broken", timeout=1.0)
    ch.close()


# --------------------------------------------------------------------------------------- probe
class ScriptedServer:
    """A one-connection TCP server on 127.0.0.1 that plays ``script(conn)`` in a thread."""

    def __init__(self, script):
        self.sock = socket.create_server(("127.0.0.1", 0))
        self.port = self.sock.getsockname()[1]
        self.received: list[tuple[int, bytes]] = []
        self.done = threading.Event()
        self.thread = threading.Thread(target=self._run, args=(script,), daemon=True)
        self.thread.start()

    def _run(self, script):
        self.sock.settimeout(2.0)
        try:
            conn, _ = self.sock.accept()
        except OSError:
            return
        with conn:
            conn.settimeout(2.0)
            try:
                script(self, conn)
            except OSError:
                pass
            self.done.wait(2.0)

    def read(self, conn) -> tuple[int, bytes]:
        head = conn.recv(3, socket.MSG_WAITALL)
        size, kind = struct.unpack(">HB", head)
        body = conn.recv(size - 3, socket.MSG_WAITALL) if size > 3 else b""
        self.received.append((kind, body))
        return kind, body

    @staticmethod
    def send(conn, kind: str, payload: bytes) -> None:
        conn.sendall(struct.pack(">HB", 3 + len(payload), ord(kind)) + payload)

    def close(self):
        self.done.set()
        self.sock.close()
        self.thread.join(3.0)


def _handshake(stream: bool):
    def script(server, conn):
        server.read(conn)
        server.send(conn, "V", b"\x01")
        server.read(conn)
        server.send(conn, "v", struct.pack(">IIII", 5, 12, 1, 1234))
        server.read(conn)
        server.send(conn, "M", b"\x05hello")  # a text message the client must skip
        server.send(conn, "O", b"\x01DOUBLE")
        server.read(conn)
        server.send(conn, "S", b"\x01")
        if stream:
            server.send(conn, "U", b"\x01" + struct.pack(">d", 12.5))
    return script


@pytest.fixture
def serve(monkeypatch):
    servers = []

    def start(script) -> ScriptedServer:
        server = ScriptedServer(script)
        monkeypatch.setattr(probe, "RTDE_PORT", server.port)
        servers.append(server)
        return server

    yield start
    for server in servers:
        server.close()


def test_probe_handshake_reads_controller_version(serve):
    server = serve(_handshake(stream=True))
    info = probe.rtde_handshake("127.0.0.1", timeout=1.0)
    assert info.version == (5, 12, 1, 1234) and info.series == "e-Series"
    assert info.data_rate_hz == 500.0 and info.uses_dashboard
    kinds = [chr(k) for k, _ in server.received]
    assert kinds == ["V", "v", "O", "S"]
    assert server.received[0][1] == b"\x00\x02"
    out = server.received[2][1]
    assert struct.unpack(">d", out[:8])[0] == probe.PROBE_FREQUENCY_HZ
    assert out[8:] == b"timestamp,"


def test_probe_controller_that_never_streams_fails_within_timeout(serve):
    serve(_handshake(stream=False))
    with pytest.raises(ConnectionFailed, match=r"127\.0\.0\.1:\d+ .*no first data package within "
                                               r"0\.2 s"):
        probe.rtde_handshake("127.0.0.1", timeout=0.2)


def test_probe_server_that_hangs_up_is_named(serve):
    serve(lambda server, conn: (server.read(conn), conn.close()))
    with pytest.raises(ConnectionFailed, match="closed the connection"):
        probe.rtde_handshake("127.0.0.1", timeout=1.0)


def test_check_controller_needs_the_dashboard_port(serve, monkeypatch):
    serve(_handshake(stream=True))
    monkeypatch.setattr(probe, "DASHBOARD_PORT", _closed_port())
    with pytest.raises(ConnectionFailed, match="dashboard server"):
        probe.check_controller("127.0.0.1", timeout=1.0)


def test_controller_info_generations():
    assert ControllerInfo("h", (3, 15, 7, 0)).data_rate_hz == 125.0
    polyscope_x = ControllerInfo("h", (10, 7, 0, 0))
    assert not polyscope_x.uses_dashboard and not polyscope_x.accepts_script_upload
    assert ControllerInfo("h", (10, 11, 0, 0)).accepts_script_upload
