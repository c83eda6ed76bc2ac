"""armstereo fuse: the JSON keys the issue names, the summary, one-line errors with exit codes."""

import json

import pytest

from armstereo.cli.main import main
from tests.armstereo.fusion.synthetic import ROI, record_small_scan

ROI_ARG = "--roi=" + ",".join(f"{v:g}" for v in ROI.as_list())  # starts with a minus sign


@pytest.fixture(scope="module")
def scan(tmp_path_factory):
    path = tmp_path_factory.mktemp("scan") / "scan.mcap"
    record_small_scan(path, "ring:3")
    return path


def test_json_report_has_the_named_keys(scan, tmp_path, capsys):
    code = main(["fuse", str(scan), "--out", str(tmp_path), "--voxel", "0.004", ROI_ARG,
                 "--workers", "1", "--json"])
    assert code == 0
    report = json.loads(capsys.readouterr().out)
    assert report["views"] == 3 and report["voxel_m"] == 0.004
    assert isinstance(report["timings_s"], dict) and report["timings_s"]["total"] > 0
    for key in ("accuracy_mean_mm", "completeness_mean_mm", "within_2mm",
                "completeness_within_5mm"):
        assert isinstance(report["accuracy"][key], float)
    assert (tmp_path / "mesh.ply").exists() and (tmp_path / "fused.ply").exists()


def test_summary_without_json(scan, tmp_path, capsys):
    code = main(["fuse", str(scan), "--out", str(tmp_path), "--voxel", "0.006", ROI_ARG,
                 "--trunc", "0.02", "--workers", "1", "--depth-source", "truth"])
    assert code == 0
    out = capsys.readouterr().out
    assert "fused 3 pair(s) at 6 mm voxels" in out and "accuracy" in out and "mesh.ply" in out


@pytest.mark.parametrize("args,code,text", [
    (["--roi", "1,2,3"], 2, "--roi must be"),
    (["--roi=-0.5,-0.4,-0.2,-0.1,2,2.5"], 2, "outside every view"),
    (["--voxel", "-1"], 2, "--voxel"),
])
def test_errors_are_one_line_with_exit_codes(scan, tmp_path, capsys, args, code, text):
    assert main(["-q", "fuse", str(scan), "--out", str(tmp_path), "--workers", "1",
                 *args]) == code
    err = capsys.readouterr().err.strip()
    assert err.startswith("armstereo fuse: error:") and text in err and "\n" not in err


def test_missing_recording_is_a_bad_argument_like_everywhere(tmp_path, capsys):
    assert main(["fuse", str(tmp_path / "nope.mcap"), "--out", str(tmp_path)]) == 2
    assert "argument SCAN.mcap: no such file" in capsys.readouterr().err
