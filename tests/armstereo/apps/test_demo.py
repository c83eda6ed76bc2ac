"""The demo runs end to end on the mock backends and its report is computed from ground truth."""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest

from armstereo.apps.demo import DemoOptions, score_reconstruction
from armstereo.cli.main import main
from armstereo.io.ply import read_ply
from armstereo.reconstruct.pipeline import reconstruct_pair
from armstereo.reconstruct.stereo_options import BirchfieldOptions
from armstereo.recording import Recording

# What the realistic demo measures with seed 0 after calibrating the cell and removing the
# vignetting and the exposure difference (bench/results/cell.md has seeds 0-9; before the
# calibration and the photometric correction: 0.702 %, 69 %, 3.11 mm).
REALISTIC_MEASURED = {"median": 0.00284, "density": 0.867, "point_mm": 1.33}

# The whole demo (capture, match, write) twice per module (ideal and realistic): about 15 s.
pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def demo_dir(tmp_path_factory):
    """The ideal profile: exact kinematics and camera, the matcher-friendly table scene."""
    out = tmp_path_factory.mktemp("demo")
    assert main(["demo", "--mock-profile", "ideal", "--out", str(out)]) == 0
    return out


@pytest.fixture(scope="module")
def realistic_dir(tmp_path_factory):
    """The default: the realistic profile."""
    out = tmp_path_factory.mktemp("demo_realistic")
    assert main(["demo", "--out", str(out)]) == 0
    return out


def test_demo_writes_every_file_and_a_complete_report(demo_dir):
    report = json.loads((demo_dir / "report.json").read_text())
    assert isinstance(report["points"], int) and report["points"] > 100_000
    assert {"capture", "match", "total"} <= set(report["timings_s"])
    acc = report["accuracy"]
    for key in ("median_abs_rel_depth_error", "within_1pct", "density"):
        assert isinstance(acc[key], float)
    # Regression bounds near what the demo measures (0.022 % median, 93.3 % within 1 %,
    # density 93.9 %; 96.5 % and 99.1 % before the ideal profile's photo check removed the
    # fattened edges, bench/results/footprint.md); the product's targets are 0.5 % and 90 %.
    assert acc["median_abs_rel_depth_error"] <= 0.0003
    assert acc["within_1pct"] >= 0.92
    assert acc["density"] >= 0.92
    for name in ("disparity.png", "rectified.png", "depth_error.png"):
        img = cv2.imread(str(demo_dir / name))
        assert img is not None and img.shape[0] > 100
    assert len(read_ply(demo_dir / "points.ply").points) == report["points"]
    assert len(Recording.open(demo_dir / "demo.mcap")) == 1


def test_demo_accuracy_is_measured_against_ground_truth(demo_dir):
    report = json.loads((demo_dir / "report.json").read_text())
    pair = Recording.open(demo_dir / "demo.mcap")[0]
    # the report says which matcher options made it, so it can be reproduced
    assert report["matcher_options"] == DemoOptions(profile="ideal").matcher_options()
    assert report["matcher"] == {"method": "birchfield",
                                 "options": DemoOptions(profile="ideal").matcher().as_dict()}
    recon = reconstruct_pair(pair, stereo_options=report["matcher_options"])
    again = reconstruct_pair(pair, stereo=BirchfieldOptions(**report["matcher"]["options"]))
    np.testing.assert_array_equal(again.disparity, recon.disparity)
    same = score_reconstruction(recon.depth_original, pair, swapped=recon.swapped)
    assert same.median_abs_rel_depth_error == pytest.approx(
        report["accuracy"]["median_abs_rel_depth_error"], rel=1e-6)
    shifted = score_reconstruction(recon.depth_original * 1.01, pair, swapped=recon.swapped)
    assert shifted.median_abs_rel_depth_error > 0.009
    assert shifted.within_1pct < same.within_1pct
    holes = recon.depth_original.copy()
    holes[:, ::2] = np.nan
    assert score_reconstruction(holes, pair, swapped=recon.swapped).density < 0.55


def test_demo_refuses_a_folder_that_holds_a_previous_demo(demo_dir, capsys):
    assert main(["demo", "--out", str(demo_dir)]) == 2
    assert "already holds demo files" in capsys.readouterr().err


def test_bad_option_fails_before_a_folder_is_made(tmp_path, capsys):
    out = tmp_path / "never"
    assert main(["demo", "--baseline", "5", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "argument --baseline: 5 m exceeds the cap of 0.5 m" in err and err.count("\n") == 1
    assert not out.exists()


def test_demo_finds_every_object_on_the_table_and_scores_them(demo_dir):
    scene = json.loads((demo_dir / "report.json").read_text())["scene"]
    score = scene["score"]
    assert len(scene["objects"]) == score["true_objects"] == 7
    assert score["missed"] == [] and score["phantoms"] == []
    assert score["plane_tilt_deg"] < 0.05 and abs(score["plane_height_error_m"]) < 0.0005
    assert score["worst"]["height_error_m"] < 0.002  # measured 0.2 mm
    assert (demo_dir / "scene" / "scene.json").is_file()
    assert (demo_dir / "scene" / "scene_top.png").is_file()


def test_realistic_demo_reads_the_calibration_checks_and_carries_its_budget(realistic_dir):
    report = json.loads((realistic_dir / "report.json").read_text())
    assert report["profile"] == "realistic"
    kin = report["kinematics"]
    assert kin["source"] == "controller" and kin["warnings"] == []
    assert 1.0 < kin["nominal_vs_calibrated_workspace_max"]["translation_mm"] < 15.0
    rec = Recording.open(realistic_dir / "demo.mcap")
    assert rec.metadata["kinematics_source"] == "controller"
    assert rec.metadata["dh_sha256"] == kin["dh_sha256"]
    # our FK is the arm's: the poses agree with what its controller reports
    assert report["check"]["fk_vs_controller_max_mm"] < 0.01
    assert report["check"]["warnings"] == []
    budget = report["error_budget"]
    assert budget["sources"] == ["kinematics (calibrated arm)", "hand-eye error",
                                 "intrinsics error", "image effects", "joint noise",
                                 "arm pose residual"]
    assert budget["median_abs_rel_depth_error"] == report["accuracy"][
        "median_abs_rel_depth_error"]
    # Bounds near what it measures (seed 0: REALISTIC_MEASURED); a real arm's errors, not the
    # ideal mock's 0.02 %.
    acc = report["accuracy"]
    assert REALISTIC_MEASURED["median"] / 2 < acc["median_abs_rel_depth_error"] \
        < REALISTIC_MEASURED["median"] * 1.5
    assert acc["density"] >= REALISTIC_MEASURED["density"] - 0.03
    point = report["point_error_mm"]
    assert point["median"] < REALISTIC_MEASURED["point_mm"] * 1.5


def test_realistic_demo_calibrates_first_and_says_what_it_bought(realistic_dir):
    """The workflow: the cell's camera calibrated (mount file, recording and report kept),
    the desk captured with that mount file, and the same pair with the bundled mount file
    for comparison."""
    report = json.loads((realistic_dir / "report.json").read_text())
    for name in ("camera.toml", "calibration.mcap", "calibration.json"):
        assert (realistic_dir / name).is_file()
    assert report["cell"] == "realistic seed 0" and report["mount"]["file"] == "camera.toml"
    cal = report["calibration"]
    true, predicted = cal["truth_error"], cal["predicted_error"]
    assert true["translation_m"] < 0.0003 and true["rotation_deg"] < 0.05
    assert abs(true["focal_rel"]) < 0.001 and abs(true["vignetting_corner_rel"]) < 0.02
    assert 0.25 < true["translation_m"] / predicted["translation_m"] < 4
    rec = Recording.open(realistic_dir / "demo.mcap")
    assert "[vignetting]" in rec.metadata["mount_toml"]  # the capture used camera.toml
    assert rec.metadata["mock_cell"] == "realistic seed 0"
    photo = report["photometric"]
    assert photo["vignetting"]["applied"] and photo["exposure"]["requested"]
    before = report["before"]
    assert before["mount"] == "default_wrist_camera"
    assert before["accuracy"]["median_abs_rel_depth_error"] > \
        3 * report["accuracy"]["median_abs_rel_depth_error"]
    assert before["point_error_mm"]["median"] > 3 * report["point_error_mm"]["median"]


def test_realistic_demo_fits_the_table_within_the_issue_bounds(realistic_dir):
    """Issue 24's scene gate on the demo's own run (seed 0, Birchfield-Tomasi, calibrated):
    plane tilt at most 0.3 deg and height within 1 mm. Measured: 0.21 deg, -0.52 mm at the
    table's centre (+0.89 mm at the base origin, as scored before), 6 of 7 found (the 2 mm
    notes pad is never an object), no phantom; before the plane's cell refit
    (armstereo.scene.plane.refine_from_cells) the height was +1.6 mm at the base origin."""
    score = json.loads((realistic_dir / "report.json").read_text())["scene"]["score"]
    assert score["plane_tilt_deg"] <= 0.3
    assert abs(score["plane_height_error_m"]) <= 0.001
    assert score["phantoms"] == [] and len(score["missed"]) <= 1


def test_realistic_desk_is_harder_than_the_ideal_table(demo_dir, realistic_dir):
    ideal = json.loads((demo_dir / "report.json").read_text())
    real = json.loads((realistic_dir / "report.json").read_text())
    assert real["accuracy"]["median_abs_rel_depth_error"] > \
        10 * ideal["accuracy"]["median_abs_rel_depth_error"]
    assert ideal["point_error_mm"]["median"] < 0.2  # exact poses: sub-millimetre points
