"""``armstereo calibrate --arm ur`` through the real ur_rtde client against the emulated UR
controller (tests/rtde_emulator; real time), with the mock camera on its flange: the
controller's calibrated kinematics are read and used, every view is reached by a checked
moveJ, and the calibration finds the mock camera's truth."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from armstereo.devices import MotionLimits
from armstereo.recording import Recording
from armstereo.robot.arm_model import ArmModel
from armstereo.robot.synthetic import synthetic_calibration
from drivers.mock.start_poses import table_start
from tests.rtde_emulator import DEFAULT_CALIBRATION_SEED
from tests.rtde_emulator.harness import EmulatedController

pytestmark = pytest.mark.slow  # real-time controller emulation: about 30 s

VIEWS = 6


def armstereo_command() -> list[str]:
    script = Path(sys.executable).with_name("armstereo")
    return [str(script)] if script.exists() else [sys.executable, "-m", "armstereo"]


def test_calibrate_on_an_emulated_ur_arm(tmp_path):
    model = ArmModel.from_dh(synthetic_calibration("ur5e", DEFAULT_CALIBRATION_SEED),
                             mount="default_wrist_camera")
    q0 = table_start(model)
    emu = EmulatedController(q0=q0)
    try:
        out = tmp_path / "cam.toml"
        done = subprocess.run(
            armstereo_command() + ["-q", "calibrate", "--arm", "ur", "--host", emu.host,
                                   "--camera", "mock", "--robot", "ur5e", "--board",
                                   "chessboard:17x12:0.016", "--views", str(VIEWS), "--out",
                                   str(out), "--yes", "--json", "--speed", "0.25",
                                   "--acceleration", "1.0", "--settle", "0.1"],
            capture_output=True, text=True, timeout=240)
        assert done.returncode == 0, done.stderr
        report = json.loads(done.stdout)
        assert report["kinematics"]["source"] == "controller"
        assert report["kinematics"]["dh_sha256"] == model.dh.sha256
        err = report["truth_error"]
        assert err["translation_m"] < 0.001 and err["rotation_deg"] < 0.1
        assert abs(err["focal_rel"]) < 0.005
        # Every view was reached by one moveJ at most at the joint caps, then back home.
        cmds = [c for c in emu.commands() if c["name"] != "isSteady"]
        moves = [c for c in cmds if c["name"] == "moveJ"]
        assert len(moves) == VIEWS  # views 1..5 and the return (view 0 is the start)
        limits = MotionLimits()
        assert all(0 < c["speed"] <= limits.joint_speed for c in moves)
        assert not any(c["name"] == "moveL" for c in cmds)
        assert np.allclose(emu.state()["q"], q0, atol=1e-6)
        rec = Recording.open(out.with_suffix(".mcap"))
        assert len(rec.views) == VIEWS and rec.metadata["arm"] == "ur"
    finally:
        emu.close()
