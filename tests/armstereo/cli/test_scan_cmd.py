"""armstereo scan: dry run, a small scan end to end with fuse, refusals and faults as one line
with capture's exit codes."""

import pytest

from armstereo.cli.main import main
from armstereo.recording import Recording

TARGET = "--target=-0.45,-0.13,0.03"  # the mock table scene's centre; starts with a minus sign
BASE = ["scan", TARGET, "--baseline", "0.06"]


def test_dry_run_prints_the_plan_and_moves_nothing(tmp_path, capsys):
    out = tmp_path / "s.mcap"
    assert main([*BASE, "--views", "ring:2", "--out", str(out), "--dry-run"]) == 0
    text = capsys.readouterr().out
    assert "scan plan: ring:2" in text and "2 of 2 viewpoints kept" in text
    assert "tour pre-flight checks:" in text and "FAIL" not in text
    assert text.rstrip().endswith("dry run: nothing moved")
    assert not out.exists()


def test_scan_then_fuse(tmp_path, capsys):
    out = tmp_path / "s.mcap"
    assert main(["-q", *BASE, "--views", "ring:2", "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "recorded 4 views, 2 pair(s)" in text and "viewpoint" in text
    rec = Recording.open(out)
    assert len(rec) == 2 and rec.warnings == [] and rec.metadata["kind"] == "scan"
    assert rec.metadata["kinematics_source"] == "nominal"
    fused = tmp_path / "fused"
    assert main(["-q", "fuse", str(out), "--out", str(fused), "--voxel", "0.006",
                 "--depth-source", "truth", "--workers", "1"]) == 0
    assert "accuracy" in capsys.readouterr().out and (fused / "mesh.ply").exists()


@pytest.mark.parametrize("args,code,text", [
    (["--target", "2.5,0,0"], 3, "'viewpoints' failed: none of the"),
    (["--views", "ring:4", "--workspace=-0.46,0.85,-0.85,0.85,0.05,0.85"], 3,
     "'workspace' failed: camera at"),
    (["--views", "ring:0"], 2, "argument --views"),
    (["--views", "auto"], 2, "argument --views"),
    (["--target", "1,2"], 2, "argument --target"),
    (["--radius", "0.01"], 2, "--radius must be"),
    (["--baseline", "0.6"], 2, "argument --baseline"),
    (["--inject-fault", "disconnect@3"], 4, "2 view(s) kept"),
])
def test_errors_are_one_line_with_capture_s_exit_codes(tmp_path, capsys, args, code, text):
    out = tmp_path / "s.mcap"
    assert main(["-q", *BASE, "--views", "ring:2", "--out", str(out), *args]) == code
    err = capsys.readouterr().err.strip()
    assert err.startswith("armstereo scan: error:") and text in err and "\n" not in err
    if code != 4:
        assert not out.exists()


def test_a_fault_keeps_complete_pairs_for_fuse(tmp_path, capsys):
    out = tmp_path / "s.mcap"
    # moves: 1 joints, 2 baseline, 3 joints, 4 baseline, 5 joints back: the link drops on the
    # way back, after both pairs
    assert main(["-q", *BASE, "--views", "ring:2", "--out", str(out), "--inject-fault",
                 "disconnect@5"]) == 4
    assert "4 view(s) kept" in capsys.readouterr().err
    assert len(Recording.open(out)) == 2
    assert main(["-q", "fuse", str(out), "--out", str(tmp_path / "f"), "--voxel", "0.006",
                 "--depth-source", "truth", "--workers", "1"]) == 0


def test_existing_output_is_not_overwritten(tmp_path, capsys):
    out = tmp_path / "s.mcap"
    out.write_bytes(b"precious")
    assert main([*BASE, "--out", str(out)]) == 2
    assert out.read_bytes() == b"precious" and "--force" in capsys.readouterr().err
