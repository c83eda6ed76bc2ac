"""Bad input ends with one line and the documented exit code, and leaves nothing broken behind
(issue 10's list, one test per case)."""

from __future__ import annotations

import errno
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from armstereo.cli.main import main
from armstereo.io import files
from armstereo.recording import Recording, RecordingWriter
from tests.support import MIDDLEBURY, ROOT, SAMPLE_RECORDING


def run(capsys, *argv) -> tuple[int, str, list[str]]:
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, [line for line in err.splitlines() if line.strip()]


def one_line(err: list[str], *words: str) -> None:
    assert len(err) == 1, err
    assert "Traceback" not in err[0] and "internal error" not in err[0]
    for w in words:
        assert w in err[0], err


@pytest.mark.parametrize("argv,words", [
    (["capture", "--speed", "0"], ["--speed", "> 0"]),
    (["capture", "--acceleration", "0"], ["--acceleration", "> 0"]),
    (["capture", "--settle", "inf"], ["--settle", "finite"]),
    (["capture", "--settle", "nan"], ["--settle", "finite"]),
    (["sweep", "--speed", "0"], ["--speed", "> 0"]),
])
def test_zero_and_non_finite_motion_values_are_refused_before_anything(tmp_path, capsys, argv,
                                                                       words, monkeypatch):
    monkeypatch.chdir(tmp_path)
    out = tmp_path / ("rec.mcap" if argv[0] == "capture" else "sweep")
    code, _, err = run(capsys, *argv, "--out", out)
    assert code == 2
    one_line(err, *words)
    assert list(tmp_path.iterdir()) == []  # no MCAP, no folder


def test_plan_refuses_nan_accuracy(capsys):
    code, _, err = run(capsys, "plan", "--near", "0.4", "--far", "0.8", "--depth-accuracy", "nan")
    assert code == 2
    one_line(err, "--depth-accuracy")


def test_full_disk_names_the_file_and_keeps_what_was_complete(tmp_path, capsys, monkeypatch):
    real = files.tempfile.mkstemp
    calls = {"n": 0}

    def fills_up(*args, **kwargs):
        calls["n"] += 1
        if calls["n"] > 1:  # the PLY is written, then the disk is full
            raise OSError(errno.ENOSPC, "No space left on device")
        return real(*args, **kwargs)

    monkeypatch.setattr(files.tempfile, "mkstemp", fills_up)
    out = tmp_path / "out"
    code, _, err = run(capsys, "-q", "reconstruct", SAMPLE_RECORDING, "--out", out)
    assert code == 5
    one_line(err, "No space left on device", str(out / "pair000_depth.png"))
    assert (out / "pair000.ply").stat().st_size > 1000  # the complete output stays


def test_read_only_output_folder_is_a_named_error(tmp_path, capsys, monkeypatch):
    def read_only(self, *args, **kwargs):
        raise OSError(errno.EROFS, "Read-only file system")

    monkeypatch.setattr(Path, "mkdir", read_only)
    code, _, err = run(capsys, "demo", "--out", tmp_path / "ro" / "demo")
    assert code == 5
    one_line(err, "Read-only file system", "ro/demo")


def test_a_second_writer_of_the_same_recording_fails_at_once(tmp_path, capsys):
    out = tmp_path / "same.mcap"
    with RecordingWriter(out, metadata={"who": "first"}):
        code, _, err = run(capsys, "capture", "--out", out, "--force")
        assert code == 2
        one_line(err, "being written by another process")
    assert Recording.open(out).metadata["who"] == "first"  # not emptied by the second


@pytest.mark.parametrize("argv", [
    ["demo", "--robot", "foo"],
    ["demo", "--robot", "ur3e"],
    ["sweep", "--baselines", "0.6"],
    ["sweep", "--distances", "0.05"],
])
def test_failed_runs_leave_no_folder(tmp_path, capsys, argv):
    out = tmp_path / "new" / "run"
    code, _, err = run(capsys, "-q", *argv, "--out", out)
    assert code == 2
    one_line(err)
    assert not (tmp_path / "new").exists()


def test_a_refused_demo_capture_leaves_no_empty_recording(tmp_path, capsys):
    """The capture's checks run before the calibration: a refused capture writes nothing."""
    code, _, err = run(capsys, "-q", "demo", "--baseline", "0.5", "--out", tmp_path / "d")
    assert code == 3
    one_line(err, "pre-flight")
    assert not (tmp_path / "d").exists()


def test_quiet_silences_demo_progress():
    proc = subprocess.run([sys.executable, "-m", "armstereo", "-q", "demo", "--robot", "ur3e",
                           "--out", "/nonexistent-armstereo-dir/x"], capture_output=True,
                          text=True, cwd=ROOT, timeout=120)
    assert proc.returncode == 2
    assert len(proc.stderr.strip().splitlines()) == 1  # the error, no "[1/4] ..." progress


@pytest.mark.parametrize("mount_text,words", [
    ("[hand_eye]\ntranslation = [0, 0, 0]\nrotation_rpy = [nan, 0, 0]\n"
     "[camera]\nwidth = 64\nheight = 48\nK = [[50, 0, 32], [0, 50, 24], [0, 0, 1]]\n",
     ["hand_eye.rotation_rpy", "finite"]),
    ("[hand_eye]\ntranslation = [0, 0, 0]\n"
     "[camera]\nwidth = 64\nheight = 48\nK = [[0, 0, 32], [0, 50, 24], [0, 0, 1]]\n",
     ["fx, fy > 0"]),
])
def test_bad_mount_fields_are_named_in_one_line(tmp_path, capsys, mount_text, words):
    mount = tmp_path / "m.toml"
    mount.write_text(mount_text)
    for argv in (["plan", "--near", "0.4", "--far", "0.8", "--depth-accuracy", "0.004"],
                 ["capture", "--dry-run", "--out", tmp_path / "x.mcap"]):
        code, _, err = run(capsys, *argv, "--mount", mount)
        assert code == 2
        one_line(err, str(mount), *words)


def test_a_rotation_typed_with_few_decimals_works_everywhere(tmp_path, capsys):
    R = np.round([[0.9950042, -0.0998334, 0.0], [0.0998334, 0.9950042, 0.0], [0, 0, 1]], 4)
    mount = tmp_path / "m.toml"
    mount.write_text("[hand_eye]\ntranslation = [0.0, -0.07, 0.04]\n"
                     f"rotation_matrix = {json.dumps(R.tolist())}\n"
                     "[camera]\nwidth = 640\nheight = 480\n"
                     "K = [[600, 0, 319.5], [0, 600, 239.5], [0, 0, 1]]\n")
    rec = tmp_path / "r.mcap"
    assert run(capsys, "-q", "capture", "--mount", mount, "--out", rec)[0] == 0
    assert run(capsys, "-q", "reconstruct", rec, "--out", tmp_path / "o")[0] == 0


def test_eval_refuses_a_colour_photograph(capsys):
    teddy = MIDDLEBURY / "teddy"
    code, _, err = run(capsys, "eval", teddy / "imL.png", teddy / "groundtruth.png")
    assert code == 2
    one_line(err, "colour image, not a disparity map")


@pytest.mark.parametrize("command", ["inspect", "reconstruct"])
def test_missing_and_directory_inputs_have_one_code(tmp_path, capsys, command):
    code, _, err = run(capsys, command, tmp_path / "missing.mcap")
    assert code == 2
    one_line(err, "no such file")
    code, _, err = run(capsys, command, tmp_path)
    assert code == 2
    one_line(err, "is a directory")


def test_sweep_errors_print_plain_numbers(tmp_path, capsys):
    code, _, err = run(capsys, "sweep", "--distances", "0.05", "--out", tmp_path / "s")
    assert code == 2
    one_line(err, "0.05")
    assert "np.float64" not in err[0]


def test_inspect_tells_an_interrupted_capture(tmp_path, capsys):
    rec = tmp_path / "cut.mcap"
    code, _, _ = run(capsys, "-q", "capture", "--pairs", "3", "--inject-fault",
                     "disconnect@2", "--out", rec)
    assert code == 4
    code, out, _ = run(capsys, "inspect", rec, "--json")
    summary = json.loads(out)
    assert any("asked for 3 pair(s) but 1 complete" in w for w in summary["warnings"])


@pytest.mark.parametrize("argv,flag", [
    (["capture", "--host", "10.0.0.2"], "--host"),
    (["sweep", "--target", "10,10,50,50=1.0"], "--target"),
])
def test_flags_for_another_backend_are_refused_not_ignored(tmp_path, capsys, argv, flag):
    code, _, err = run(capsys, *argv, "--out", tmp_path / "x")
    assert code == 2
    one_line(err, flag)
