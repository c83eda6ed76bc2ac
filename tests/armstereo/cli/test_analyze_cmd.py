"""``armstereo analyze``: files, --json, scoring, and one-line errors with their exit codes."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from armstereo.cli.main import main
from armstereo.io.ply import write_ply
from armstereo.recording import RecordingWriter
from armstereo.scene.synthetic import default_truth, scan
from armstereo.transforms import rot_x

SAMPLE = Path(__file__).parents[3] / "recordings" / "sample.mcap"


@pytest.fixture(scope="module")
def ply(tmp_path_factory):
    cloud = scan(default_truth(), spacing=0.002, noise=0.0003)
    path = tmp_path_factory.mktemp("in") / "table.ply"
    return write_ply(path, cloud.points, cloud.colors_bgr, comment="synthetic, frame base")


def test_analyze_writes_the_files_and_prints_the_object_table(ply, tmp_path, capsys):
    assert main(["analyze", str(ply), "--out", str(tmp_path / "s")]) == 0
    out = capsys.readouterr().out
    assert "objects: 4" in out and "sphere" in out and "plane:" in out
    for name in ("scene.json", "scene.mcap", "scene_top.png", "height_map.npz",
                 "occupancy.npz"):
        assert (tmp_path / "s" / name).is_file()


def test_default_output_folder_sits_beside_the_input(ply, capsys):
    assert main(["-q", "analyze", str(ply)]) == 0
    assert (ply.parent / "table_scene" / "scene.json").is_file()


def test_json_prints_exactly_scene_json(ply, tmp_path, capsys):
    assert main(["analyze", str(ply), "--out", str(tmp_path), "--json", "--cell", "0.01"]) == 0
    printed = capsys.readouterr().out
    assert json.loads(printed) == json.loads((tmp_path / "scene.json").read_text())
    assert json.loads(printed)["height_map"]["cell_m"] == 0.01


def test_truth_file_scores_the_analysis(ply, tmp_path, capsys):
    truth = tmp_path / "truth.json"
    truth.write_text(default_truth().to_json())
    assert main(["analyze", str(ply), "--out", str(tmp_path / "s"), "--truth", str(truth)]) == 0
    assert "4 of 4 objects found, missed: none, phantoms: none" in capsys.readouterr().out
    score = json.loads((tmp_path / "s" / "scene_score.json").read_text())
    assert score["worst"]["center_error_m"] < 0.002


def test_flat_min_area_finds_a_sheet_and_zero_switches_it_off(tmp_path, capsys):
    from armstereo.evaluation.scene_truth import SceneTruth
    from armstereo.scene.synthetic import box, table
    truth = SceneTruth([table(), box("sheet", 0.05, 0.0, 0.2, 0.14, 0.002)], "table")
    cloud = scan(truth, spacing=0.002, noise=0.0015)
    path = write_ply(tmp_path / "sheet.ply", cloud.points, cloud.colors_bgr)
    found = []
    for extra in ([], ["--flat-min-area", "0"]):
        assert main(["analyze", str(path), "--out", str(tmp_path / "s"), "--json", *extra]) == 0
        found.append(json.loads(capsys.readouterr().out)["objects"])
    assert len(found[0]) == 1 and found[0][0]["top"] == "flat" and found[1] == []
    assert main(["analyze", str(path), "--out", str(tmp_path), "--flat-min-area", "-1"]) == 2
    assert "--flat-min-area" in capsys.readouterr().err


def test_recording_metadata_truth_is_used(tmp_path, capsys):
    cloud = scan(default_truth(), spacing=0.003)
    rec = tmp_path / "r.mcap"
    with RecordingWriter(rec, metadata={"scene_truth": default_truth().to_json()}) as w:
        w.write_point_cloud(cloud.points, cloud.colors_bgr, 5)
    assert main(["analyze", str(rec), "--out", str(tmp_path / "s")]) == 0
    assert "score:" in capsys.readouterr().out


@pytest.mark.parametrize("args, code, text", [
    (["--up", "1,2"], 2, "three numbers"),
    (["--up", "0,0,0"], 2, "non-zero"),
    (["--max-tilt", "-1"], 2, "--max-tilt: must be in [0, 90]"),
    (["--cell", "0.01", "--occupancy-cell", "0.005"], 2, "finer"),
    (["--truth", "/nonexistent.json"], 2, "no such file"),
])
def test_bad_options_exit_2_with_one_line(ply, tmp_path, capsys, args, code, text):
    assert main(["analyze", str(ply), "--out", str(tmp_path), *args]) == code
    err = capsys.readouterr().err
    assert text in err and err.count("\n") == 1


def test_inclined_cloud_exits_6_and_passes_with_up(tmp_path, capsys):
    cloud = scan(default_truth(), spacing=0.003)
    R = rot_x(math.radians(25.0))
    path = write_ply(tmp_path / "tilted.ply", cloud.points @ R.T, cloud.colors_bgr,
                     comment="frame base")
    assert main(["analyze", str(path), "--out", str(tmp_path / "a")]) == 6
    assert "--up" in capsys.readouterr().err
    up = ",".join(f"{v:.6f}" for v in R[:, 2])
    assert main(["analyze", str(path), "--out", str(tmp_path / "b"), "--up", up]) == 0


def test_bad_inputs_exit_with_their_codes(tmp_path, capsys):
    empty = write_ply(tmp_path / "empty.ply", np.zeros((0, 3), np.float32),
                      np.zeros((0, 3), np.uint8), comment="frame base")
    assert main(["analyze", str(empty), "--out", str(tmp_path / "a")]) == 2
    assert "empty" in capsys.readouterr().err
    assert main(["analyze", str(SAMPLE), "--out", str(tmp_path / "b")]) == 5
    assert "/points" in capsys.readouterr().err
    blob = np.random.default_rng(0).uniform(-0.15, 0.15, size=(2000, 3))
    noplane = write_ply(tmp_path / "blob.ply", blob, np.zeros((2000, 3), np.uint8),
                        comment="frame base")
    assert main(["analyze", str(noplane), "--out", str(tmp_path / "c")]) == 6
    assert "no support plane" in capsys.readouterr().err
