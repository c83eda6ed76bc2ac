"""armstereo demo --scan: scan, fuse, render and score into one folder, with a summary."""

import json

import cv2
import numpy as np
import pytest

from armstereo.apps.scan_demo import SCAN_DEMO_FILES
from armstereo.cli.main import main


@pytest.fixture(scope="module")
def demo(tmp_path_factory):
    out = tmp_path_factory.mktemp("scan_demo") / "d"
    import contextlib
    import io

    stdout = io.StringIO()
    with contextlib.redirect_stdout(stdout):
        code = main(["-q", "demo", "--scan", "--views", "ring:2", "--mock-profile", "ideal",
                     "--no-calibrate", "--out", str(out)])
    return code, stdout.getvalue(), out


def test_writes_every_file_and_a_report(demo):
    code, text, out = demo
    assert code == 0
    # without the calibration: no mount file, calibration files or bundled fusion
    assert {p.name for p in out.iterdir()} == set(SCAN_DEMO_FILES) - {
        "camera.toml", "calibration.mcap", "calibration.json", "fused_bundled"}
    assert {p.name for p in (out / "fused").iterdir()} >= {"mesh.ply", "fused.ply",
                                                          "fusion.mcap", "report.json"}
    report = json.loads((out / "report.json").read_text())
    assert report["profile"] == "ideal" and report["camera_noise"] == 1.0
    assert report["pairs"] == report["viewpoints_kept"] == 2
    assert {"scan", "fuse_reconstruct", "fuse_integrate", "fuse_score", "render",
            "total"} <= set(report["timings_s"])
    assert report["accuracy"]["accuracy_mean_mm"] < 1.5
    assert set(report["targets"]) == {"accuracy_mean_mm", "completeness_within_5mm", "met"}
    for word in ("cell:", "camera:", "scan:", "fused:", "accuracy:", "complete:", "time:",
                 "memory:", "files:"):
        assert word in text


def test_the_picture_shows_the_mesh(demo):
    _, _, out = demo
    image = cv2.imread(str(out / "mesh.png"))
    assert image is not None and image.shape == (480, 1280, 3)
    drawn = np.any(image != 255, axis=2)
    assert 0.2 < drawn[:, :640].mean() < 0.95  # the colour half: mesh and background
    assert 0.2 < drawn[:, 640:].mean() < 0.95  # the shape half


def test_views_without_scan_is_refused(tmp_path, capsys):
    assert main(["demo", "--views", "ring:2", "--out", str(tmp_path / "d")]) == 2
    assert "--views applies to --scan only" in capsys.readouterr().err
    assert not (tmp_path / "d").exists()


def test_a_bad_layout_fails_before_a_folder_is_made(tmp_path, capsys):
    assert main(["demo", "--scan", "--views", "ring:x", "--out", str(tmp_path / "d")]) == 2
    assert "--views must be" in capsys.readouterr().err
    assert not (tmp_path / "d").exists()
