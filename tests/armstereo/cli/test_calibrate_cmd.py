"""armstereo calibrate end to end on the mock: the camera's truth found, the mount file capture
reads, --from reproducing the session, the kinematics trap, dry run and one-line errors."""

from __future__ import annotations

import contextlib
import io
import json
from pathlib import Path

import numpy as np
import pytest

from armstereo.calibration.mount_file import truth_error
from armstereo.calibration.session import mock_true_mount, read_calibration_session
from armstereo.cli.main import main
from armstereo.mount import CameraMount
from armstereo.recording import Recording
from armstereo.robot.arm_model import ArmModel
from bench.harness import capture_and_score

BOARD = "chessboard:17x12:0.016"
# Issue 12's targets on the mock: realistic profile, and the ideal one.
REALISTIC_TARGET = (0.001, 0.1, 0.005)  # m, deg, relative focal length
IDEAL_TARGET = (0.0003, 0.05, 0.005)


def calibrate(out: Path, *args: str) -> tuple[int, str, str]:
    """Run ``armstereo -q calibrate --out OUT ARGS``; (exit code, stdout, stderr)."""
    stdout, stderr = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(stdout), contextlib.redirect_stderr(stderr):
        code = main(["-q", "calibrate", "--out", str(out), *args])
    return code, stdout.getvalue(), stderr.getvalue()


def live_session(folder: Path, profile: str, seed: int) -> tuple[dict, Path, Path]:
    """A 15-view calibration on the mock: (JSON report, mount file, recording)."""
    out = folder / f"cam_{profile}_{seed}.toml"
    code, stdout, stderr = calibrate(out, "--board", BOARD, "--mock-profile", profile,
                                     "--seed", str(seed), "--json")
    assert code == 0, stderr
    return json.loads(stdout), out, out.with_suffix(".mcap")


def within(err: dict, target: tuple[float, float, float]) -> bool:
    return (err["translation_m"] < target[0] and err["rotation_deg"] < target[1]
            and abs(err["focal_rel"]) < target[2])


@pytest.fixture(scope="module")
def realistic(tmp_path_factory):
    return live_session(tmp_path_factory.mktemp("calibrate"), "realistic", 0)


def test_realistic_mock_calibration_finds_the_true_camera(realistic):
    report, out, recording = realistic
    assert within(report["truth_error"], REALISTIC_TARGET), report["truth_error"]
    assert report["warnings"] == []
    # The mount file the mock started from (a CAD guess and datasheet intrinsics) is far from
    # the cell's camera: the calibrator found it, its vignetting too.
    truth = mock_true_mount(read_calibration_session(recording))
    start = truth_error(CameraMount.load(None), truth)
    assert start["translation_m"] > 0.002 and start["rotation_deg"] > 0.8
    assert abs(start["focal_rel"]) > 0.015 and np.abs(truth.intrinsics.dist[:2]).min() > 0.01
    assert abs(report["truth_error"]["vignetting_corner_rel"]) < 0.02
    assert CameraMount.load(out).vignetting is not None
    # with the controller's calibrated kinematics, as capture uses them
    assert report["kinematics"]["source"] == "controller"
    assert report["views"]["used"] == list(range(15))


def test_mount_file_is_what_capture_and_reconstruct_read(realistic):
    report, out, recording = realistic
    mount = CameraMount.load(out)
    assert mount.name == out.stem
    np.testing.assert_array_equal(mount.T_flange_camera, report["T_flange_camera"])
    np.testing.assert_array_equal(mount.intrinsics.K, report["intrinsics"]["K"])
    np.testing.assert_array_equal(mount.intrinsics.dist, report["intrinsics"]["dist"])
    assert ArmModel.load("ur5e", mount=out).mount.name == out.stem
    meta = Recording.open(recording).metadata
    assert meta["purpose"] == "calibration" and meta["calibration_board"] == BOARD
    assert meta["kinematics_source"] == "controller" and meta["mock_profile"] == "realistic"
    assert report["mount_file"] == str(out) and report["recording"]["path"] == str(recording)
    with contextlib.redirect_stdout(io.StringIO()):
        assert main(["-q", "inspect", str(recording)]) == 0  # views and no pairs: fine here


def test_from_reproduces_the_recorded_session(realistic, tmp_path):
    report, out, recording = realistic
    again = tmp_path / "again.toml"
    code, stdout, stderr = calibrate(again, "--from", str(recording), "--json")
    assert code == 0, stderr
    redo = json.loads(stdout)
    for key in ("T_flange_camera",):
        np.testing.assert_allclose(redo[key], report[key], rtol=0, atol=1e-9)
    for key in ("K", "dist"):
        np.testing.assert_allclose(redo["intrinsics"][key], report["intrinsics"][key], rtol=0,
                                   atol=1e-9)
    for key in ("translation_m", "rotation_deg", "focal_rel"):
        assert redo["truth_error"][key] == pytest.approx(report["truth_error"][key], abs=1e-9)


def test_nominal_kinematics_bias_the_hand_eye_and_the_report_says_so(realistic, tmp_path):
    """The issue's trap: the same views with the nominal model's poses (``--robot ur5e``)
    instead of the arm's calibrated kinematics."""
    report, _, recording = realistic
    code, stdout, stderr = calibrate(tmp_path / "nominal.toml", "--from", str(recording),
                                     "--robot", "ur5e", "--json")
    assert code == 0, stderr
    nominal = json.loads(stdout)
    assert nominal["kinematics"]["source"] == "given"
    good, bad = report["truth_error"], nominal["truth_error"]
    assert bad["translation_m"] > 5 * good["translation_m"]
    assert bad["rotation_deg"] > 5 * good["rotation_deg"]
    assert any("calibrated kinematics" in w for w in nominal["warnings"])


def test_from_with_the_wrong_board_says_it_is_not_found(realistic, tmp_path):
    _, _, recording = realistic
    out = tmp_path / "cam.toml"
    code, _, stderr = calibrate(out, "--from", str(recording), "--board",
                                "charuco:14x10:0.02:0.015")
    assert code == 2 and stderr.count("\n") == 1
    assert "board not found in 15 of 15 views" in stderr and not out.exists()


def test_dry_run_plans_and_checks_every_move_and_writes_nothing(tmp_path):
    out = tmp_path / "cam.toml"
    code, stdout, stderr = calibrate(out, "--board", BOARD, "--dry-run")
    assert code == 0, stderr
    assert "calibration plan: 15 views" in stdout and "view 14 -> start" in stdout
    for check in ("speed caps", "start pose", "joint limits", "singularity", "workspace",
                  "tool speed"):
        assert f"[ok] {check}:" in stdout
    assert stdout.rstrip().endswith("dry run: nothing moved")
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("args,code,text", [
    (["--board", "chessboard:9x6:0.008"], 2, "too small in the start image"),
    (["--board", "chessboard:4x4:0.05"], 2, "looks the same turned by 180 degrees"),
    ([], 2, "--board is required"),
    (["--board", BOARD, "--views", "3"], 2, "--views"),
    (["--board", BOARD, "--workspace=-1,1,-1,1,0.6,1"], 3, "'workspace' failed"),
    (["--from", "{rec}", "--dry-run"], 2, "--dry-run do(es) not apply"),
])
def test_bad_input_is_one_line_with_its_exit_code(tmp_path, args, code, text):
    rec = tmp_path / "some.mcap"
    rec.write_bytes(b"")
    out = tmp_path / "cam.toml"
    got, _, stderr = calibrate(out, *[a.replace("{rec}", str(rec)) for a in args])
    assert got == code, stderr
    assert stderr.count("\n") == 1 and stderr.startswith("armstereo calibrate: error:")
    assert text in stderr
    assert not out.exists() and not out.with_suffix(".mcap").exists()


def test_too_similar_views_are_refused_and_the_recording_is_kept(tmp_path):
    out = tmp_path / "cam.toml"
    code, _, stderr = calibrate(out, "--board", BOARD, "--views", "6", "--max-tilt", "5",
                                "--max-roll", "0")
    assert code == 2
    assert stderr.count("\n") == 1 and "views are too similar" in stderr
    recording = out.with_suffix(".mcap")
    assert f"the recording {recording} is kept" in stderr and "--from" in stderr
    assert len(Recording.open(recording).views) == 6 and not out.exists()


@pytest.mark.slow
def test_rotations_about_one_axis_only_are_refused(tmp_path):
    out = tmp_path / "cam.toml"
    code, _, stderr = calibrate(out, "--board", BOARD, "--views", "8", "--max-tilt", "5",
                                "--max-roll", "90", "--corner-views", "0")
    assert code == 2 and stderr.count("\n") == 1
    assert "about parallel axes" in stderr and "is kept" in stderr


def test_a_camera_fault_keeps_the_views_recorded_so_far(tmp_path):
    out = tmp_path / "cam.toml"
    # grab 1 is the start image; grabs 2-4 are views 0-2; grab 5 times out
    code, _, stderr = calibrate(out, "--board", BOARD, "--inject-fault", "camera-timeout@5")
    assert code == 4 and stderr.count("\n") == 1
    assert "3 view(s) kept" in stderr
    assert len(Recording.open(out.with_suffix(".mcap")).views) == 3 and not out.exists()


@pytest.mark.slow
def test_ideal_profile_reaches_the_tighter_targets(tmp_path):
    report, _, _ = live_session(tmp_path, "ideal", 0)
    assert within(report["truth_error"], IDEAL_TARGET), report["truth_error"]


@pytest.mark.slow
def test_predicted_error_is_within_a_factor_two_of_the_true_error(realistic, tmp_path):
    """Over seeds, the RMS of the true hand-eye error against the RMS of the leave-one-out
    prediction (one seed's error is a single draw; its spread is what is predicted)."""
    reports = [realistic[0]] + [live_session(tmp_path, "realistic", s)[0] for s in (1, 2, 3)]
    for key in ("translation_m", "rotation_deg"):
        true = np.sqrt(np.mean([r["truth_error"][key] ** 2 for r in reports]))
        predicted = np.sqrt(np.mean([r["quality"]["predicted_error"][key] ** 2
                                     for r in reports]))
        assert 0.5 <= true / predicted <= 2.0, (key, true, predicted)


def test_a_mount_file_from_calibrate_makes_capture_on_the_cell_more_accurate(realistic,
                                                                             tmp_path):
    """One cell for both commands: the mount file ``calibrate`` wrote makes ``capture`` on the
    same cell (profile and seed) as accurate as the camera's true mount, and far more accurate
    than the bundled mount file it started from."""
    from dataclasses import replace

    _, out, recording = realistic
    bundled = CameraMount.load(None)
    true = replace(mock_true_mount(read_calibration_session(recording)), name="true")
    scores = {m.name: capture_and_score(tmp_path, m, "realistic", 0)
              for m in (CameraMount.load(out), true, replace(bundled, name="bundled"))}
    (cal_depth, cal_points), (true_depth, true_points) = scores[out.stem], scores["true"]
    assert cal_depth <= 1.1 * true_depth + 2e-4, scores
    assert cal_points <= 1.1 * true_points + 0.1, scores
    # the bundled mount (a CAD hand-eye guess, datasheet intrinsics): several times worse
    assert scores["bundled"][0] > 3 * cal_depth and scores["bundled"][1] > 3 * cal_points
