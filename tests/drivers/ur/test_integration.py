"""URArm and ``armstereo capture --arm ur`` through the real ur_rtde client against an emulated
UR controller (tests/rtde_emulator): RTDE, dashboard and script port on a loopback address of
its own, in its own process, playing ur_rtde's control-script register protocol in real time.

The emulated arm carries a factory calibration (the emulator's default kinematics), which
URArm and the capture read from its primary stream at connect.

What these tests cannot show (only a real arm can): real motion timing and repeatability,
PolyScope's remote-control and safety settings, a real controller's own kinematic calibration.
"""

from __future__ import annotations

import json
import re
import subprocess
import sys
import time
from pathlib import Path
from typing import NamedTuple

import numpy as np
import pytest

from armstereo.capture import session
from armstereo.cli.main import main
from armstereo.devices import ArmState
from armstereo.errors import (
    ConnectionFailed,
    ConnectionLost,
    MotionTimeout,
    ProtectiveStop,
)
from armstereo.recording import Recording
from armstereo.recording.inspect import summarize
from armstereo.robot.arm_model import ArmModel
from armstereo.robot.dh import pose_difference
from armstereo.robot.synthetic import synthetic_calibration
from drivers.mock.start_poses import table_start as mock_start_configuration
from drivers.ur.arm import URArm
from drivers.ur.channel import ControlChannel
from drivers.ur.probe import rtde_handshake
from tests.rtde_emulator import DEFAULT_CALIBRATION_SEED
from tests.rtde_emulator.harness import EmulatedController, free_loopback_address

# Real-time controller emulation: about 45 s for the file.
pytestmark = pytest.mark.slow

BASELINE_TOL_M = 0.0005
FAST = ["--speed", "0.25", "--acceleration", "1.0", "--settle", "0.1"]  # a 0.1 m move: 0.65 s
FAIL_FAST_S = 5.0  # a refused or silent controller must be reported within seconds


@pytest.fixture(scope="module")
def model() -> ArmModel:
    """The emulated UR5e's own calibrated kinematics (what URArm reads at connect)."""
    return ArmModel.from_dh(synthetic_calibration("ur5e", DEFAULT_CALIBRATION_SEED),
                            mount="default_wrist_camera")


@pytest.fixture(scope="module")
def q_start(model) -> np.ndarray:
    """Where the mock camera sees the mock scene: the emulated arm starts here."""
    return mock_start_configuration(model)


@pytest.fixture
def start_emulator(q_start):
    """Factory for emulated controllers; every one started is ended after the test."""
    started: list[EmulatedController] = []

    def start(**kwargs) -> EmulatedController:
        kwargs.setdefault("q0", q_start)
        emu = EmulatedController(**kwargs)
        started.append(emu)
        return emu

    yield start
    for emu in started:
        emu.close()


@pytest.fixture
def control_calls(monkeypatch) -> list[str]:
    """Names of the ur_rtde control calls URArm makes (spied, then passed through)."""
    calls: list[str] = []
    original = ControlChannel.call

    def spy(self, method, *args, timeout, **kwargs):
        calls.append(method)
        return original(self, method, *args, timeout=timeout, **kwargs)

    monkeypatch.setattr(ControlChannel, "call", spy)
    return calls


@pytest.fixture
def capture_errors(monkeypatch) -> list[BaseException]:
    """Exceptions that leave run_capture, before the CLI turns them into a line and a code."""
    errors: list[BaseException] = []
    original = session.run_capture

    def spy(*args, **kwargs):
        try:
            return original(*args, **kwargs)
        except BaseException as err:
            errors.append(err)
            raise

    monkeypatch.setattr(session, "run_capture", spy)
    return errors


class Connected(NamedTuple):
    """A URArm connected to an emulated controller."""

    arm: URArm
    emu: EmulatedController


@pytest.fixture
def fresh(start_emulator, model) -> Connected:
    """A connected URArm on its own emulator, for tests that change the controller's state."""
    emu = start_emulator()
    arm = URArm(emu.host, model)
    arm.connect()
    yield Connected(arm, emu)
    arm.close()


@pytest.fixture(scope="module")
def shared(model, q_start) -> Connected:
    """A connected URArm on an emulator shared by tests that leave it as they found it
    (closing ur_rtde's interfaces costs 2 s: each disconnect sleeps 0.5 s, twice)."""
    emu = EmulatedController(q0=q_start)
    try:
        arm = URArm(emu.host, model)
        arm.connect()
        yield Connected(arm, emu)
        arm.close()
    finally:
        emu.close()


def capture_args(host: str, out: Path, *extra: str) -> list[str]:
    return ["capture", "--arm", "ur", "--host", host, "--camera", "mock", "--robot", "ur5e",
            "--baseline", "0.1", "--pairs", "2", "--out", str(out), "--yes", *extra]


def armstereo_command() -> list[str]:
    script = Path(sys.executable).with_name("armstereo")
    return [str(script)] if script.exists() else [sys.executable, "-m", "armstereo"]


def assert_no_protocol_errors(emu: EmulatedController) -> None:
    bad = [e for e in emu.events() if e["kind"] == "protocol_error"
           or (e["kind"] == "command" and e["name"].startswith("unsupported"))]
    assert not bad, bad


def assert_views_readable(out: Path, views: int) -> Recording:
    """The recording holds ``views`` complete views with decodable images; every complete
    pair achieved the baseline."""
    rec = Recording.open(out)
    assert [v.index for v in rec.views] == list(range(views))
    for v in rec.views:
        assert v.image.shape[:2] == (v.intrinsics.height, v.intrinsics.width)
    assert len(rec) == views - 1
    for pair in rec:
        assert abs(pair.achieved_baseline_m - 0.1) < BASELINE_TOL_M
    return rec


# ------------------------------------------------------------------------------ full capture
def test_cli_capture_against_the_emulator_achieves_the_baseline(start_emulator, q_start, model,
                                                                tmp_path):
    emu = start_emulator()
    out = tmp_path / "rec.mcap"
    done = subprocess.run(armstereo_command() + capture_args(emu.host, out, *FAST),
                          text=True, capture_output=True, timeout=120)
    assert done.returncode == 0, done.stderr
    assert "recorded 3 views, 2 pair(s)" in done.stdout
    rec = assert_views_readable(out, 3)
    assert rec.metadata["arm"] == "ur" and rec.metadata["host"] == emu.host
    # The controller's calibrated table was read at connect and recorded; every view's pose
    # (our FK of the recorded joints) is within 0.01 mm of the controller's own.
    assert rec.metadata["kinematics_source"] == "controller"
    assert rec.metadata["dh_sha256"] == model.dh.sha256
    assert json.loads(rec.metadata["dh_table"]) == model.dh.as_dict()
    assert rec.metadata["calibration_status"] == "2"
    for v in rec.views:
        lin, ang = pose_difference(v.T_base_flange, v.controller_T_base_flange)
        assert lin < 1e-5 and ang < 1e-6
    summary = summarize(rec)
    assert summary["fk_vs_controller_max_mm"] < 0.01 and summary["warnings"] == []
    # The recorded joints are the controller's: camera poses from their FK, 0.1 m apart.
    cams = [model.camera_pose(v.joint_positions)[:3, 3] for v in rec.views]
    R_base_camera = model.camera_pose(q_start)[:3, :3]
    for a, b in zip(cams, cams[1:], strict=False):
        assert np.linalg.norm((b - a) - R_base_camera @ [0.1, 0, 0]) < BASELINE_TOL_M
    # What the controller received: zero TCP, three async moveL (two views and back), each
    # run to its end, then the script stopped by close().
    cmds = [c for c in emu.commands() if c["name"] != "isSteady"]
    assert [c["name"] for c in cmds] == ["setTcp", "moveL", "moveL", "moveL", "stopL",
                                         "stopScript"]
    assert cmds[0]["pose"] == [0.0] * 6
    assert all(c["asynchronous"] and c["speed"] == 0.25 for c in cmds[1:4])
    assert [e["completed"] for e in emu.events("motion_end")] == [True] * 3
    state = emu.state()
    assert np.allclose(state["q"], q_start, atol=1e-9) and state["runtime_state"] == 1
    assert_no_protocol_errors(emu)


# ------------------------------------------------------------------------ URArm and ur_rtde
def test_urarm_reads_and_moves_through_ur_rtde(shared, model):
    arm, emu = shared
    assert arm.status().state is ArmState.NORMAL
    assert arm.controller.version == (5, 12, 0, 1101534)
    # FK with the table read at connect reproduces the controller's pose (to the rounding of
    # its rotation-vector TCP pose).
    assert arm.kinematics.calibrated and max(arm.fk_mismatch) < 1e-9
    q1, t1 = arm.joint_positions(), arm.last_controller_timestamp
    q2, t2 = arm.joint_positions(), arm.last_controller_timestamp
    assert np.allclose(q2, q1) and t2 > t1  # each reading comes from a newer RTDE package
    seen = len(emu.commands())

    q_goal = q1 + np.array([0.1, -0.05, 0.05, 0.0, 0.0, -0.1])
    arm.move_joints(q_goal, speed=1.0, acceleration=2.0)
    assert np.allclose(arm.joint_positions(), q_goal, atol=1e-9)
    T_goal = model.flange_pose(q_goal)
    T_goal[:3, 3] += [0.03, -0.02, 0.04]
    arm.move_linear(T_goal, speed=0.25, acceleration=1.0)
    arm.wait_until_steady(timeout=2.0)
    assert np.allclose(arm.controller_flange_pose(), T_goal, atol=1e-7)
    assert np.allclose(model.flange_pose(arm.joint_positions()), T_goal, atol=1e-7)

    moves = [c for c in emu.commands()[seen:] if c["name"] in ("moveJ", "moveL")]
    assert [(c["name"], c["asynchronous"]) for c in moves] == [("moveJ", True),
                                                               ("moveL", True)]
    assert [e["completed"] for e in emu.events("motion_end")[-2:]] == [True, True]
    arm.move_joints(q1, speed=1.0, acceleration=2.0)  # leave the shared arm where it was
    assert_no_protocol_errors(emu)


def test_ur_rtde_sync_and_async_moves_progress_stop_steady_and_tcp(shared):
    """The raw client on the emulator: the calls URArm builds on behave as on a controller.
    It uses the arm's own ur_rtde interfaces (a second control interface would be refused)."""
    import rtde_control
    import rtde_receive

    arm, emu = shared
    rc: rtde_control.RTDEControlInterface = arm._ch.target
    rr: rtde_receive.RTDEReceiveInterface = arm._rr
    q_initial = np.array(rr.getActualQ())
    pose = np.array(rr.getActualTCPPose())
    target = pose + [0.0, 0.05, 0.0, 0.0, 0.0, 0.0]
    t0 = time.monotonic()
    assert rc.moveL(target.tolist(), 0.25, 1.2)  # blocking: returns when the move is done
    assert time.monotonic() - t0 > 0.3 and rc.isSteady()
    time.sleep(0.01)  # the TCP pose can be one RTDE period stale right after the move
    assert np.allclose(rr.getActualTCPPose(), target, atol=1e-7)
    idle = rc.getAsyncOperationProgress()
    assert idle in (-1, -2)

    q = np.array(rr.getActualQ())
    assert rc.moveJ((q + [0.5, 0, 0, 0, 0, 0]).tolist(), 0.5, 1.0, True)  # returns at once
    time.sleep(0.1)
    assert rc.getAsyncOperationProgress() >= 0 and not rc.isSteady()
    assert rc.stopJ(4.0) is None  # void in ur_rtde
    stopped = rc.getAsyncOperationProgress()
    assert stopped < 0 and stopped != idle  # a new operation id ended
    assert rc.isSteady()
    q_stop = np.array(rr.getActualQ())
    assert 0.0 < q_stop[0] - q[0] < 0.5  # stopped part way

    try:
        rc.setTcp([0.0, 0.0, 0.1, 0.0, 0.0, 0.0])
        assert rc.getTCPOffset() == pytest.approx([0.0, 0.0, 0.1, 0.0, 0.0, 0.0])
        time.sleep(0.01)
        flange = arm.model.flange_pose(rr.getActualQ())
        assert np.allclose(rr.getActualTCPPose()[:3], flange[:3, 3] + flange[:3, 2] * 0.1,
                           atol=1e-9)
    finally:
        rc.setTcp([0.0] * 6)  # URArm relies on the zero TCP it set at connect
    assert rc.poseTrans([0.1, 0, 0, 0, 0, np.pi / 2], [0.1, 0, 0, 0, 0, 0]) == pytest.approx(
        [0.1, 0.1, 0, 0, 0, np.pi / 2])
    assert rc.moveJ(q_initial.tolist(), 1.0, 2.0)  # leave the shared arm where it was
    assert_no_protocol_errors(emu)


def test_cb3_controller_another_model_and_upper_range_registers(start_emulator):
    """A CB3 (PolyScope 3.15: 125 Hz, no serial-number or remote-control queries) with a UR5,
    driven through input/output registers 24-47: the rate ur_rtde asks for is honoured, the
    register offset comes from the uploaded script, the model's kinematics are used."""
    q0 = np.array([0.2, -1.7, 1.6, -1.5, -1.57, 0.3])
    emu = start_emulator(robot="ur5", q0=q0, version="3.15.7.106331")
    arm = URArm(emu.host, ArmModel.load("ur5"), upper_range_registers=True)
    arm.connect()
    ur5 = arm.model  # the CB3's calibrated UR5 table, read at connect
    try:
        assert arm.kinematics.calibrated and ur5.dh.model == "ur5"
        assert arm.controller.series == "CB3" and emu.rate_hz == 125.0
        arm.joint_positions()
        t1 = arm.last_controller_timestamp
        arm.joint_positions()
        periods = (arm.last_controller_timestamp - t1) * 125.0
        assert periods >= 2 - 1e-6 and abs(periods - round(periods)) < 1e-6  # 8 ms packages
        T = ur5.flange_pose(q0)
        T[:3, 3] += [0.0, 0.03, 0.0]
        arm.move_linear(T, speed=0.25, acceleration=1.0)
        assert np.allclose(ur5.flange_pose(arm.joint_positions()), T, atol=1e-7)
    finally:
        arm.close()
    frequencies = {e["frequency"] for e in emu.events("rtde_outputs")}
    assert frequencies == {125.0}  # probe, receive and control interfaces
    assert [e["command"] for e in emu.events("dashboard")] == []
    assert [e["register_offset"] for e in emu.events("program_started")] == [24]
    assert_no_protocol_errors(emu)


def test_second_control_client_gets_the_registers_in_use_error(shared, model):
    import rtde_control

    arm, emu = shared
    with pytest.raises(RuntimeError, match="RTDE input registers are already in use"):
        rtde_control.RTDEControlInterface(arm.host)
    second = URArm(arm.host, model)
    with pytest.raises(ConnectionFailed, match="in use by another client"):
        second.connect()
    assert not second.is_connected
    # The first client keeps its registers and its arm.
    T_start = arm.controller_flange_pose()
    T = T_start.copy()
    T[:3, 3] += [0.0, 0.0, 0.02]
    arm.move_linear(T, speed=0.25, acceleration=1.0)
    arm.move_linear(T_start, speed=0.25, acceleration=1.0)
    assert emu.events("inputs_in_use")


def test_protective_stop_during_a_move_then_recovery_through_the_dashboard(
        fresh, control_calls):
    arm, emu = fresh
    emu.configure(unlock_delay_s=1.0)  # UR's rule is 5 s; shortened, retries still exercised
    emu.inject("protective_stop", move=1, at=0.4)
    T_start = arm.controller_flange_pose()
    T_goal = T_start.copy()
    T_goal[:3, 3] += [0.0, 0.05, 0.0]
    with pytest.raises(ProtectiveStop, match="protective stop during moveL"):
        arm.move_linear(T_goal, speed=0.25, acceleration=1.0)
    assert "stopL" in control_calls[control_calls.index("moveL"):]
    assert arm.status().state is ArmState.PROTECTIVE_STOP
    emu.wait_until_still()
    halted = emu.events("motion_end")[-1]
    assert not halted["completed"] and 0.4 <= halted["fraction"] < 1.0  # halted part way

    arm.recover_protective_stop(timeout=5.0)
    answers = [e["answer"] for e in emu.events("dashboard")
               if e["command"] == "unlock protective stop"]
    assert answers[0].startswith("Cannot unlock") and answers[-1] == "Protective stop releasing"
    assert len(emu.events("program_started")) == 2  # the control script was uploaded again
    assert arm.status().state is ArmState.NORMAL
    arm.move_linear(T_goal, speed=0.25, acceleration=1.0)
    assert np.allclose(arm.controller_flange_pose(), T_goal, atol=1e-7)


# ------------------------------------------------------------------ faults through the CLI
@pytest.mark.parametrize(("fault", "error", "pattern"), [
    ("protective_stop", ProtectiveStop, r"is in a protective stop during moveL"),
    # Which of ur_rtde's two connections notices the loss first is a race.
    ("disconnect", ConnectionLost, r"lost the (RTDE|control) connection to UR controller"),
    ("stall", MotionTimeout, r"moveL on UR controller at \S+ did not finish within"),
], ids=["protective_stop", "disconnect", "stall"])
def test_fault_during_a_capture_move_stops_and_keeps_the_views(
        start_emulator, tmp_path, capsys, monkeypatch, control_calls, capture_errors,
        fault, error, pattern):
    # A stalled move is noticed after the plan's duration + MOVE_TIMEOUT_MARGIN_S (10 s);
    # 0.5 s keeps the test short and changes nothing else.
    monkeypatch.setattr("armstereo.capture.run.MOVE_TIMEOUT_MARGIN_S", 0.5)
    emu = start_emulator()
    emu.inject(fault, move=2, at=0.5)  # move 2: from view 1 to view 2
    out = tmp_path / "rec.mcap"
    assert main(["-q", *capture_args(emu.host, out, *FAST)]) == 4
    lines = capsys.readouterr().err.strip().splitlines()
    # one error line; a dropped link may add warnings that the stop could not be sent
    err = [line for line in lines if line.startswith("armstereo capture: error:")]
    assert len(err) == 1 and re.search(pattern, err[0]) and "2 view(s) kept" in err[0], lines
    assert all("Traceback" not in line for line in lines)
    assert len(capture_errors) == 1 and type(capture_errors[0]) is error
    assert_views_readable(out, 2)

    # URArm told the arm to stop after the failed move...
    last_move = len(control_calls) - control_calls[::-1].index("moveL") - 1
    assert "stopL" in control_calls[last_move:]
    # ...and what reached the controller depends on the fault.
    fired = emu.events("fault")[0]["t"]
    after = [c["name"] for c in emu.commands() if c["t"] >= fired]
    if fault == "stall":  # the program still runs: the stop arrives and halts the arm
        stop = next(c for c in emu.commands() if c["name"] == "stopL")
        assert stop["halted_motion"] and not emu.wait_until_still()["moving"]
        assert "speed slider at 0 %" in err[0]
    elif fault == "protective_stop":  # the safety system halted it; the program is stopped,
        assert after == []            # so ur_rtde sends no command at all
        emu.wait_until_still()
        assert not emu.events("motion_end")[-1]["completed"]
    else:  # the link is gone: nothing can arrive; ur_rtde's stopL hangs, URArm gives up
        assert after == []
    assert_no_protocol_errors(emu)


def test_controller_slow_to_start_streaming(start_emulator, tmp_path, capsys):
    emu = start_emulator(settings={"start_delay_s": 30.0})
    out = tmp_path / "rec.mcap"
    t0 = time.monotonic()
    assert main(["-q", *capture_args(emu.host, out, *FAST)]) == 4
    assert time.monotonic() - t0 < FAIL_FAST_S
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "gave no first data package within 2 s" in err[0], err
    assert not out.exists() and emu.commands() == []
    # Slow but within the probe's timeout: URArm's handshake (which guards ur_rtde's
    # constructors, themselves without a timeout) waits for the first package.
    emu.configure(start_delay_s=0.5)
    t0 = time.monotonic()
    assert rtde_handshake(emu.host, timeout=2.0).version == (5, 12, 0, 1101534)
    assert 0.5 <= time.monotonic() - t0 < 2.0


def test_nothing_listening_fails_fast(model, tmp_path, capsys):
    host = free_loopback_address()
    out = tmp_path / "rec.mcap"
    t0 = time.monotonic()
    assert main(capture_args(host, out)) == 4
    assert time.monotonic() - t0 < FAIL_FAST_S
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and f"cannot reach UR controller at {host}:30004" in err[0], err
    assert not out.exists()
    t0 = time.monotonic()
    with pytest.raises(ConnectionFailed, match="Connection refused"):
        URArm(host, model).connect()
    assert time.monotonic() - t0 < FAIL_FAST_S


def test_controllers_that_must_not_be_driven_are_refused_at_connect(start_emulator, model):
    emu = start_emulator(settings={"remote_control": False})
    with pytest.raises(ConnectionFailed, match="not in Remote Control"):
        URArm(emu.host, model).connect()  # e-Series in Local mode: ur_rtde refuses
    emu.configure(remote_control=True, robot_mode=5)  # powered, brakes on
    with pytest.raises(ConnectionFailed, match=r"is not running \(robot mode IDLE \(5\)"):
        URArm(emu.host, model).connect()  # URArm refuses before ur_rtde uploads its script
    assert emu.events("script_upload") == []
