"""``armstereo scan --arm ur`` through the real ur_rtde client against the emulated UR
controller (tests/rtde_emulator): joint moves between viewpoints (moveJ), baseline moves
(moveL), the controller's calibrated kinematics recorded as capture records them, and a fault
during a joint move that stops the arm and keeps the complete pairs."""

from __future__ import annotations

import numpy as np
import pytest

from armstereo.cli.main import main
from armstereo.recording import Recording
from armstereo.robot.arm_model import ArmModel
from armstereo.robot.dh import pose_difference
from armstereo.robot.synthetic import synthetic_calibration
from drivers.mock.start_poses import table_start
from drivers.ur.channel import ControlChannel
from tests.rtde_emulator import DEFAULT_CALIBRATION_SEED
from tests.rtde_emulator.harness import EmulatedController

# Real-time controller emulation: the joint moves between viewpoints take seconds each.
pytestmark = pytest.mark.slow

TARGET = "--target=-0.45,-0.13,0.03"
FAST = ["--speed", "0.25", "--acceleration", "1.0", "--settle", "0.1"]


@pytest.fixture(scope="module")
def model() -> ArmModel:
    return ArmModel.from_dh(synthetic_calibration("ur5e", DEFAULT_CALIBRATION_SEED),
                            mount="default_wrist_camera")


@pytest.fixture
def emulator(model):
    emu = EmulatedController(q0=table_start(model))
    yield emu
    emu.close()


def scan_args(host: str, out, *extra: str) -> list[str]:
    return ["-q", "scan", "--arm", "ur", "--host", host, "--camera", "mock", "--robot", "ur5e",
            TARGET, "--views", "ring:2", "--baseline", "0.06", "--out", str(out), "--yes",
            *FAST, *extra]


def test_scan_against_the_emulator(emulator, model, tmp_path, capsys):
    out = tmp_path / "scan.mcap"
    assert main(scan_args(emulator.host, out)) == 0
    assert "recorded 4 views, 2 pair(s)" in capsys.readouterr().out
    rec = Recording.open(out)
    assert len(rec) == 2 and rec.warnings == []
    assert rec.metadata["kinematics_source"] == "controller"
    assert rec.metadata["dh_sha256"] == model.dh.sha256 and rec.metadata["arm"] == "ur"
    for v in rec.views:  # our FK of the recorded joints is the controller's own pose
        lin, ang = pose_difference(v.T_base_flange, v.controller_T_base_flange)
        assert lin < 1e-5 and ang < 1e-6
    for pair in rec:
        assert abs(pair.achieved_baseline_m - 0.06) < 0.0005 and pair.viewpoint is not None
    names = [c["name"] for c in emulator.commands()]
    assert names.count("moveJ") == 3 and names.count("moveL") == 2  # in, across, back home
    np.testing.assert_allclose(emulator.state()["q"], table_start(model), atol=1e-4)


def test_a_fault_during_a_joint_move_stops_and_keeps_the_first_pair(emulator, tmp_path, capsys,
                                                                     monkeypatch):
    calls: list[str] = []
    original = ControlChannel.call

    def spy(self, method, *args, timeout, **kwargs):
        calls.append(method)
        return original(self, method, *args, timeout=timeout, **kwargs)

    monkeypatch.setattr(ControlChannel, "call", spy)
    emulator.inject("protective_stop", move=3, at=0.5)  # the joint move to the 2nd viewpoint
    out = tmp_path / "scan.mcap"
    assert main(scan_args(emulator.host, out)) == 4
    err = [line for line in capsys.readouterr().err.splitlines()
           if line.startswith("armstereo scan: error:")]
    assert len(err) == 1 and "2 view(s) kept" in err[0]
    last_move = len(calls) - calls[::-1].index("moveJ") - 1
    assert "stopJ" in calls[last_move:]  # the arm was told to stop after the failed move
    rec = Recording.open(out)
    assert len(rec.views) == 2 and len(rec) == 1
