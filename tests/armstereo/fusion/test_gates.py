"""The issue's gates on a 12-view mock scan of the table scene at 2 mm voxels.

- ideal mock (no sensor noise), the views' exact depth fused: accuracy <= 0.15 mm and
  completeness within 2 mm >= 97 % (the plumbing gate: a half-pixel slip or a three-view
  weight threshold fails it, see test_tsdf.py);
- camera noise (1 grey level, the demo's default), Birchfield-Tomasi stereo with the
  photo-consistency check for clean views (as the demo's ideal profile) fused: mean accuracy
  <= 1.0 mm, completeness within 5 mm >= 95 %, and the model more accurate than the raw pair
  clouds;
- on both fused clouds, issue 15's scene-analysis gates (:func:`_scene_gates_on_the_fused_scan`).

Slow: about 50 s of CPU time (2.7 min wall on the loaded 2-core machine): two 12-view scans
(24 renders at 640x480 each), 12 stereo pairs, two fusions with scoring.
"""

import pytest

from armstereo import backends
from armstereo.apps.scan import ScanRequest, record_scan
from armstereo.evaluation.scene_score import score_scene
from armstereo.evaluation.scene_truth import SceneTruth
from armstereo.fusion.run import FusionOptions, fuse_recording
from armstereo.mount import CameraMount
from armstereo.reconstruct.stereo import CLEAN_PHOTO_CHECK
from armstereo.recording import Recording
from armstereo.robot.arm_model import ArmModel
from armstereo.scene.analysis import SceneOptions, analyze_scene
from armstereo.scene.cloud import load_cloud
from tests.armstereo.fusion.synthetic import TARGET

pytestmark = pytest.mark.slow
FOOTPRINT_BOUND_M = 0.0045  # measured 3.6 mm at worst (the book's length), see below


def _scan(path, camera_noise: float):
    """A ring:12 scan of the table scene recorded by what ``armstereo scan`` runs."""
    model = ArmModel.load("ur5e", mount=CameraMount.load(None))
    request = ScanRequest(target=tuple(TARGET), views="ring:12", radius=0.45,
                          elevation_deg=55.0, baseline=0.06)
    outcome = record_scan(path, request, model,
                          camera_config=backends.camera_config("mock", noise=camera_noise,
                                                               seed=1), progress=None)
    assert len(outcome.result.pairs) == 12
    return path


def test_ideal_mock_exact_depth(tmp_path):
    scan = _scan(tmp_path / "ideal.mcap", 0.0)
    report = fuse_recording(scan, tmp_path / "out",
                            FusionOptions(voxel=0.002, depth_source="truth", workers=1))
    acc = report["accuracy"]
    assert acc["accuracy_mean_mm"] <= 0.15
    assert acc["completeness_within_2mm"] >= 0.97
    _scene_gates_on_the_fused_scan(scan, tmp_path / "out" / "fused.ply")


def test_camera_noise_stereo(tmp_path):
    scan = _scan(tmp_path / "noisy.mcap", 1.0)
    report = fuse_recording(scan, tmp_path / "out", FusionOptions(
        voxel=0.002, stereo_options={"photo_check": CLEAN_PHOTO_CHECK}))
    acc = report["accuracy"]
    assert acc["accuracy_mean_mm"] <= 1.0
    assert acc["completeness_within_5mm"] >= 0.95
    assert acc["accuracy_mean_mm"] < acc["raw_pairs"]["accuracy_mean_mm"]
    _scene_gates_on_the_fused_scan(scan, tmp_path / "out" / "fused.ply")


def _scene_gates_on_the_fused_scan(scan, fused_ply):
    """Issue 15's scene gates on the fused scan: every object, none invented, the plane
    within 0.5 deg and 1 mm, centres within 3 mm, heights within 2 mm, footprints within
    FOOTPRINT_BOUND_M (the issue asks 5 mm). Measured (bench/results/fused_footprint.md):
    footprints within 3.6 mm from stereo (the book's length; the crate +3.1/+2.8 mm), 1.8 mm
    from exact depth; centres within 0.6 mm, heights within 0.5 mm. Before the level scan
    baselines and the fusion's shorter band behind surfaces: the crate 7.9 mm too wide."""
    truth = SceneTruth.from_json(Recording.open(scan).metadata["scene_truth"])
    score = score_scene(analyze_scene(load_cloud(fused_ply), SceneOptions()), truth)
    assert score.missed == () and score.phantoms == ()
    assert score.plane_tilt_deg < 0.5 and abs(score.plane_height_error_m) < 0.001
    for m in score.matched:
        assert m.center_error_m < 0.003 and abs(m.height_error_m) < 0.002, m
        assert abs(m.length_error_m) < FOOTPRINT_BOUND_M, m
        assert abs(m.width_error_m) < FOOTPRINT_BOUND_M, m
