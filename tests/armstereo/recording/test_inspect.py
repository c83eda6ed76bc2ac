"""``armstereo inspect``: text and JSON summaries, warnings, exit codes, one-line errors."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

from armstereo.cli.main import main
from armstereo.recording import RecordingWriter
from tests.support.recordings import (
    JOINTS,
    small_intrinsics,
    synthetic_views,
    write_synthetic,
)

TOP_KEYS = {"file", "size_bytes", "indexed", "truncated", "duration_s", "views", "channels",
            "pairs", "calibration", "metadata", "warnings", "fk_vs_controller_max_mm",
            "fk_vs_controller_max_deg"}
PAIR_KEYS = {"pair", "left_view", "right_view", "commanded_baseline_m", "achieved_baseline_m",
             "direction", "complete", "image_size"}
CALIBRATION_KEYS = {"width", "height", "fx", "fy", "cx", "cy", "distortion_model", "D",
                    "frame_id"}


@pytest.fixture(scope="module")
def recording(tmp_path_factory):
    path = tmp_path_factory.mktemp("inspect") / "rec.mcap"
    write_synthetic(path, 3)
    return path


def test_text_summary(recording, capsys):
    assert main(["inspect", str(recording)]) == 0
    out = capsys.readouterr().out
    assert out.startswith(f"{recording}: ") and "indexed" in out
    for text in ("/camera/image", "foxglove.CompressedImage", "armstereo.CaptureEvent",
                 "views: 3 complete", "pair 0: views 0,1  commanded 50.000 mm  achieved "
                 "50.000 mm  direction x  48x32", "calibration: 48x32  fx 40.00  fy 41.00",
                 "plumb_bob (no distortion)", "robot: ur5e", "mount_toml: (3 lines; see --json)",
                 "warnings: none"):
        assert text in out, text


def test_json_summary_has_the_documented_keys(recording, capsys):
    assert main(["inspect", str(recording), "--json"]) == 0
    s = json.loads(capsys.readouterr().out)
    assert set(s) == TOP_KEYS
    assert s["indexed"] is True and s["truncated"] is False and s["views"] == 3
    assert s["fk_vs_controller_max_mm"] is None  # no controller pose in a synthetic recording
    assert s["size_bytes"] == recording.stat().st_size and s["duration_s"] > 2.5
    assert all(set(c) == {"topic", "schema", "encoding", "messages"} for c in s["channels"])
    assert {c["topic"]: c["messages"] for c in s["channels"]}["/capture/events"] == 5
    assert [set(p) for p in s["pairs"]] == [PAIR_KEYS, PAIR_KEYS]
    assert s["pairs"][1] | {"achieved_baseline_m": 0} == {
        "pair": 1, "left_view": 1, "right_view": 2, "commanded_baseline_m": 0.05,
        "achieved_baseline_m": 0, "direction": "x", "complete": True, "image_size": [48, 32]}
    assert set(s["calibration"]) == CALIBRATION_KEYS and s["calibration"]["fy"] == 41.0
    assert s["metadata"]["mount_toml"] == "name = 'm'\n[x]\n" and s["warnings"] == []


def test_unfinished_recording_is_readable_with_warnings(tmp_path, capsys):
    path, killed = tmp_path / "live.mcap", tmp_path / "killed.mcap"
    intr = small_intrinsics()
    with RecordingWriter(path, metadata={}) as w:
        w.write_calibration(intr, 0)
        for v in synthetic_views(3, intr):
            w.write_view(v["view"], v["frame"], v["q"], JOINTS, v["T_base_flange"],
                         v["T_flange_camera"], settle_s=0.5)
        w.write_pair(0, 0, 1, 0.05, 0.05, "x")
        w.write_pair(1, 1, 2, 0.05, 0.05, "x")
        data = path.read_bytes()
    killed.write_bytes(data[:-100])  # killed while a chunk was being written
    assert main(["inspect", str(killed), "--json"]) == 0
    s = json.loads(capsys.readouterr().out)
    assert s["truncated"] is True and s["indexed"] is False
    assert [p["complete"] for p in s["pairs"]] == [True]
    assert any(w.startswith("no index") for w in s["warnings"])
    assert any(w.startswith("reading stopped at byte") for w in s["warnings"])


def test_missing_calibration_prints_the_summary_then_fails(tmp_path, capsys):
    path = tmp_path / "nocal.mcap"
    write_synthetic(path, 2, calibration=False)
    assert main(["inspect", str(path)]) == 5
    captured = capsys.readouterr()
    assert "calibration: none" in captured.out and "no camera calibration" in captured.out
    (line,) = captured.err.strip().splitlines()
    assert line.startswith("armstereo inspect: error: ") and "/camera/calibration" in line


def test_no_complete_pair_fails_with_one_line(tmp_path, capsys):
    path = tmp_path / "single.mcap"
    write_synthetic(path, 1, pairs=False)
    assert main(["inspect", str(path), "--json"]) == 5
    captured = capsys.readouterr()
    assert json.loads(captured.out)["views"] == 1
    assert "no complete stereo pair" in captured.err and len(captured.err.splitlines()) == 1


@pytest.mark.parametrize(("content", "message"), [
    (b"PK\x03\x04 this is a zip file", "is not an MCAP file (bad magic)"),
    (b"", "is empty (0 bytes), not an MCAP file"),
])
def test_not_an_mcap_file_is_one_line_and_exit_5(tmp_path, capsys, content, message):
    path = tmp_path / "x.mcap"
    path.write_bytes(content)
    assert main(["inspect", str(path)]) == 5
    captured = capsys.readouterr()
    assert captured.out == ""
    assert captured.err == f"armstereo inspect: error: {path} {message}\n"


def test_the_console_command_prints_no_traceback(tmp_path):
    path = tmp_path / "notes.txt"
    path.write_text("not a recording\n")
    done = subprocess.run([sys.executable, "-m", "armstereo", "inspect", str(path)],
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 5
    assert done.stderr == f"armstereo inspect: error: {path} is not an MCAP file (bad magic)\n"
