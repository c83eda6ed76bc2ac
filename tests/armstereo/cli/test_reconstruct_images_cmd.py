"""armstereo reconstruct-images on two temple photographs."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from armstereo.cli.main import main
from armstereo.io.ply import read_ply

DATA = Path(__file__).resolve().parents[2] / "data" / "temple_ring"
LEFT, RIGHT, FAR = (str(DATA / f"templeSR00{k}.png") for k in ("08", "09", "10"))


@pytest.mark.slow  # dense matching of a 700x500 canvas
def test_metric_reconstruction_writes_its_files(tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["reconstruct-images", LEFT, RIGHT, "--focal", "1520.4", "--baseline", "0.2236",
                 "--out", str(out)]) == 0
    assert capsys.readouterr().out.startswith("metric: metres")
    report = json.loads((out / "report.json").read_text())
    assert report["reconstruction"] == "metric"
    assert report["median_abs_dy_px"] < 0.5
    cloud = read_ply(out / "points.ply")
    assert len(cloud.points) == report["points"] > 50_000
    assert np.median(cloud.points[:, 2]) == pytest.approx(0.55, rel=0.1)
    assert (out / "disparity.png").stat().st_size > 0 and (out / "rectified.png").exists()


@pytest.mark.slow
def test_without_intrinsics_the_reconstruction_says_it_is_projective(tmp_path, capsys):
    assert main(["reconstruct-images", LEFT, RIGHT, "--out", str(tmp_path)]) == 0
    assert capsys.readouterr().out.startswith("PROJECTIVE")
    assert json.loads((tmp_path / "report.json").read_text())["reconstruction"] == "projective"


@pytest.mark.parametrize("args, code, text", [
    ([LEFT, "missing.png"], 2, "no such file"),
    ([LEFT, RIGHT, "--baseline", "0.2"], 2, "needs the focal length"),
    ([LEFT, RIGHT, "--focal", "-5"], 2, "must be > 0"),
    ([LEFT, FAR], 6, "undetermined"),
])
def test_bad_input_is_one_line_with_an_exit_code(tmp_path, capsys, args, code, text):
    assert main(["reconstruct-images", *args, "--out", str(tmp_path / "o")]) == code
    err = capsys.readouterr().err.strip()
    assert text in err and "\n" not in err
    assert not (tmp_path / "o").exists()  # nothing written on failure


def test_unreadable_image_exits_2(tmp_path, capsys):
    bad = tmp_path / "bad.png"
    bad.write_bytes(b"no image")
    assert main(["reconstruct-images", str(bad), RIGHT, "--out", str(tmp_path / "o")]) == 2
    assert "cannot read" in capsys.readouterr().err
