"""``armstereo robot-info`` against the emulated controller (tests/rtde_emulator), whose arm
carries a known seeded calibration: what it prints is that calibration, read-only."""

from __future__ import annotations

import json
import time

import numpy as np
import pytest

from armstereo.cli.main import main
from armstereo.robot.arm_model import ready_configuration
from armstereo.robot.dh import fk, fk_difference, nominal_table
from armstereo.robot.model_file import load_arm_model, load_model_file
from armstereo.robot.synthetic import synthetic_calibration
from tests.rtde_emulator.harness import EmulatedController

SEED = 3
TRUTH = synthetic_calibration("ur5e", SEED)  # what the emulated arm really is


@pytest.fixture(scope="module")
def emu():
    controller = EmulatedController(kinematics=f"calibrated:{SEED}",
                                    q0=ready_configuration("ur5e"))
    yield controller
    controller.close()


@pytest.fixture
def run(capsys, caplog):
    """Run the CLI in this process: (exit code, stdout, stderr and log messages)."""
    def go(*args: str) -> tuple[int, str, str]:
        caplog.clear()
        code = main(["robot-info", *args])
        out, err = capsys.readouterr()
        return code, out, err + caplog.text

    return go


def test_json_is_the_arms_calibration_and_save_writes_it(emu, run, tmp_path):
    path = tmp_path / "arm.json"
    code, out, _ = run("--host", emu.host, "--json", "--save", str(path))
    assert code == 0
    s = json.loads(out)
    assert s["model"] == "ur5e" and s["calibrated"] is True
    assert s["calibration_status"] == 2 and s["calibration_status_text"] == "linearised"
    assert s["software_version"] == "5.12.0.1101534"
    assert s["hash"] == TRUTH.sha256 and s["checksums"] == list(TRUTH.checksums)
    assert s["dh"] == {"theta": list(TRUTH.theta), "a": list(TRUTH.a), "d": list(TRUTH.d),
                       "alpha": list(TRUTH.alpha)}
    q = np.array(s["joints"])
    np.testing.assert_array_equal(q, ready_configuration("ur5e"))
    expected = fk_difference(TRUTH, nominal_table("ur5e"), q)
    assert s["nominal_vs_calibrated"]["translation_mm"] == pytest.approx(expected[0], rel=1e-9)
    assert s["nominal_vs_calibrated"]["rotation_deg"] == pytest.approx(expected[1], rel=1e-9)
    assert s["nominal_vs_calibrated"]["translation_mm"] > 0.1
    assert s["calibrated_vs_controller"]["translation_mm"] < 1e-6
    assert 1.0 < s["nominal_vs_calibrated_workspace_max"]["translation_mm"] < 20.0
    assert s["warnings"] == [] and s["saved_to"] == str(path)
    saved = load_model_file(path)
    assert saved.table.sha256 == TRUTH.sha256 and saved.table.source == "controller"
    assert saved.controller == {"host": emu.host, "software_version": "5.12.0.1101534"}
    arm = load_arm_model(path)
    np.testing.assert_allclose(arm.flange_pose(q), fk(TRUTH, q), atol=1e-12)
    assert not [e for e in emu.events() if e["kind"] == "primary_received"]


def test_text_report(emu, run):
    code, out, _ = run("--host", emu.host, "--port", "30011")
    assert code == 0
    assert f"UR controller {emu.host}, read-only port 30011" in out
    assert "2 (linearised), read from the controller" in out
    assert TRUTH.sha256 in out and "nominal vs calibrated FK" in out
    assert "calibrated FK vs controller  0.000 mm" in out


def test_no_table_prints_the_nominal_model_and_exits_4(emu, run, tmp_path):
    emu.configure(primary_fault="truncate")
    try:
        code, out, err = run("--host", emu.host, "--json", "--save",
                             str(tmp_path / "x.json"))
    finally:
        emu.configure(primary_fault="")
    assert code == 4
    s = json.loads(out)
    assert s["calibrated"] is False and s["hash"] == nominal_table("ur5e").sha256
    assert s["nominal_vs_calibrated"] is None and s["saved_to"] is None
    assert "truncated message" in err and "nothing saved" in err and len(err.splitlines()) == 1
    assert any("NOMINAL ur5e" in w for w in s["warnings"])
    assert not (tmp_path / "x.json").exists()


def test_unreachable_controller(run):
    # The emulator address scheme keeps 127.x.y.1 free: nothing listens there.
    start = time.monotonic()
    code, out, err = run("--host", "127.1.2.1", "--json", "--timeout", "0.5")
    assert code == 4 and time.monotonic() - start < 2.0
    s = json.loads(out)
    assert s["connected"] is False and s["host"] == "127.1.2.1"
    assert "cannot reach" in err


def test_wrong_model_and_bad_arguments(emu, run):
    code, _, err = run("--host", emu.host, "--robot", "ur10e")
    assert code == 2 and "really a ur10e" in err
    code, _, err = run("--host", emu.host, "--save", "arm.urdf")
    assert code == 2 and ".json" in err


def test_robot_file_is_checked_against_the_controller(emu, run, tmp_path):
    from armstereo.robot.model_file import save_model_file

    mine = save_model_file(tmp_path / "mine.json", TRUTH)
    code, out, _ = run("--host", emu.host, "--json", "--robot", str(mine))
    assert code == 0 and json.loads(out)["robot_file_matches"] is True
    other = save_model_file(tmp_path / "other.json", synthetic_calibration("ur5e", SEED + 1))
    code, out, err = run("--host", emu.host, "--json", "--robot", str(other))
    s = json.loads(out)
    assert code == 0 and s["robot_file_matches"] is False
    assert any("is not the table this controller reports" in w for w in s["warnings"])
