"""The controller's calibrated kinematics, read through the read-only primary stream of the
emulated controller (tests/rtde_emulator) whose arm carries a seeded factory calibration: its
FK is the controller's own pose (RTDE actual_TCP_pose), nominal FK is millimetres off, and
nothing is ever written to the controller's primary ports."""

from __future__ import annotations

import time

import numpy as np
import pytest

from armstereo.robot.arm_model import ArmModel, ready_configuration
from armstereo.robot.dh import fk, nominal_table, pose_difference
from armstereo.transforms import T_from_ur_pose, make_T
from drivers.ur.arm import URArm
from drivers.ur.primary import read_arm_kinematics, read_primary
from tests.rtde_emulator.harness import EmulatedController

SEED = 7
SAMPLES = 40
FK_TOL_M = 1e-6
FK_TOL_RAD = 1e-6
RECEIVE_VARIABLES = ["timestamp", "actual_q", "actual_TCP_pose"]


@pytest.fixture(scope="module")
def emu():
    controller = EmulatedController(kinematics=f"calibrated:{SEED}",
                                    q0=ready_configuration("ur5e"))
    yield controller
    controller.close()


@pytest.fixture(scope="module")
def calibrated(emu):
    return read_arm_kinematics(emu.host, "ur5e")


def random_joints(n: int) -> np.ndarray:
    q = np.random.default_rng(SEED).uniform(-np.pi, np.pi, size=(n, 6))
    q[:, 2] = np.clip(q[:, 2], -3.0, 3.0)  # the elbow stays inside its +-pi limit
    return q


def read_pose_at(emu: EmulatedController, rr, q: np.ndarray) -> np.ndarray:
    """Teleport the emulated arm to ``q``, then T_base_tcp as RTDE reports it there."""
    emu.request("teleport", q=q.tolist())
    deadline = time.monotonic() + 2.0
    while True:
        # actual_q and actual_TCP_pose come from one package: re-read if it changed between.
        t0, got, pose, t1 = (rr.getTimestamp(), np.array(rr.getActualQ()),
                             np.array(rr.getActualTCPPose()), rr.getTimestamp())
        if t0 == t1 and np.array_equal(got, q):
            return T_from_ur_pose(pose)
        assert time.monotonic() < deadline, "the emulator did not report the teleported joints"
        time.sleep(0.002)


def test_reads_the_calibration_at_connect(emu, calibrated):
    assert calibrated.calibrated and calibrated.warnings == ()
    assert calibrated.table.model == "ur5e" and calibrated.table.calibration_status == 2
    reading = calibrated.reading
    assert str(reading.version) == "5.12.0.1101534" and reading.seconds < 1.0
    # A real calibration's table: d of the parallel joints far away, FK millimetres off.
    assert max(abs(d) for d in calibrated.table.d[1:4]) > 1.0
    assert 1.0 < calibrated.nominal_difference.translation_mm < 20.0
    # The joints and TCP pose of the same message agree with the table too.
    lin, ang = pose_difference(fk(calibrated.table, reading.joints),
                               T_from_ur_pose(reading.tcp_pose))
    assert lin < FK_TOL_M and ang < FK_TOL_RAD


def test_calibrated_fk_is_the_controllers_pose_nominal_is_millimetres_off(emu, calibrated):
    import rtde_receive

    rr = rtde_receive.RTDEReceiveInterface(emu.host, -1.0, RECEIVE_VARIABLES)
    try:
        q = random_joints(SAMPLES)
        reported = np.array([read_pose_at(emu, rr, qi) for qi in q])
    finally:
        rr.disconnect()
        emu.request("teleport", q=ready_configuration("ur5e").tolist())
    lin, ang = pose_difference(fk(calibrated.table, q), reported)
    assert lin.max() < FK_TOL_M and ang.max() < FK_TOL_RAD
    lin_nominal, _ = pose_difference(fk(nominal_table("ur5e"), q), reported)
    assert np.median(lin_nominal) > 1e-3 and lin_nominal.min() > 1e-4


def test_a_move_lands_where_the_calibrated_model_says(emu, calibrated):
    # What capture will do once it plans with the controller's table: the commanded flange
    # pose, computed with the calibrated model, is where the arm ends up.
    model = ArmModel.from_dh(calibrated.table)
    arm = URArm(emu.host, model)
    arm.connect()
    try:
        assert arm.fk_mismatch[0] < FK_TOL_M and arm.fk_mismatch[1] < FK_TOL_RAD
        target = model.flange_pose(arm.joint_positions()) @ make_T(np.eye(3), [0.05, 0, 0])
        arm.move_linear(target, speed=0.25, acceleration=1.0)
        q = arm.joint_positions()
    finally:
        arm.close()
    lin, ang = pose_difference(fk(calibrated.table, q), target)
    assert lin < FK_TOL_M and ang < FK_TOL_RAD
    # The nominal model would place this flange elsewhere (0.24 mm at this pose, seed 7).
    lin_nominal, _ = pose_difference(fk(nominal_table("ur5e"), q), target)
    assert lin_nominal > 100 * FK_TOL_M


def test_nothing_written_and_executing_ports_never_opened(emu, calibrated):
    read_primary(emu.host, port=30011)
    events = [e for e in emu.events() if e["kind"].startswith("primary")]
    ports = {e["port"] for e in events if e["kind"] == "primary_connect"}
    assert ports and ports <= {30011, 30012}
    assert not [e for e in events if e["kind"] == "primary_received"]


@pytest.mark.parametrize("fault, calibrated_expected", [
    ("resized", True), ("truncate", False), ("short_kinematics", False)])
def test_stream_faults(emu, fault, calibrated_expected):
    emu.configure(primary_fault=fault)
    try:
        result = read_arm_kinematics(emu.host, "ur5e", timeout=0.6)
    finally:
        emu.configure(primary_fault="")
    assert result.calibrated == calibrated_expected
    if not calibrated_expected:
        assert result.table == nominal_table("ur5e") and "NOMINAL" in result.warnings[-1]


def test_nominal_emulator_broadcasts_like_ursim():
    emu = EmulatedController(kinematics="nominal")
    try:
        result = read_arm_kinematics(emu.host)
    finally:
        emu.close()
    assert result.table.model == "ur5e" and result.nominal_difference == (0.0, 0.0)
    assert result.table.calibration_status == 0
    assert any("URSim" in w for w in result.warnings)
