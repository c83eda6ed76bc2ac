"""Mock multi-view scans: one pair per viewpoint, poses from the arm, truth in the metadata."""

import json

import numpy as np
import pytest

from armstereo.capture.scan_plan import ScanPlan, ViewLayout
from armstereo.errors import ConfigError
from armstereo.evaluation.scene_truth import SceneTruth
from armstereo.fusion.mock_scan import record_mock_scan
from armstereo.recording import Recording
from tests.armstereo.fusion.synthetic import TARGET, record_small_scan, small_model


@pytest.fixture(scope="module")
def scan(tmp_path_factory):
    path = tmp_path_factory.mktemp("scan") / "scan.mcap"
    plan, result = record_small_scan(path, "ring:3", camera_noise=0.0)
    return plan, result, Recording.open(path)


def test_one_pair_per_viewpoint_in_tour_order(scan):
    plan, result, rec = scan
    assert result.pairs == len(rec) == len(plan.views) == 3
    assert rec.warnings == []
    meta = json.loads(rec.metadata["scan_viewpoints"])
    assert [m["viewpoint"] for m in meta] == [v.index for v in plan.views]
    for pair, view in zip(rec, plan.views, strict=True):
        np.testing.assert_allclose(pair.left.T_base_camera, view.T_base_left, atol=1e-6)
        np.testing.assert_allclose(pair.right.T_base_camera, view.T_base_right, atol=1e-6)
        assert pair.achieved_baseline_m == pytest.approx(plan.baseline, abs=1e-6)
        assert pair.direction == "x"


def test_views_look_at_the_target_and_carry_ground_truth(scan):
    _, result, rec = scan
    truth = SceneTruth.from_json(rec.metadata["scene_truth"])
    assert truth.to_json() == result.scene_truth_json
    view = rec[0].left
    assert view.depth is not None and np.isfinite(view.depth).mean() > 0.99
    T, K, z = view.T_base_camera, view.intrinsics.K, float(view.depth[120, 160])
    ray = np.array([(160 - K[0, 2]) / K[0, 0], (120 - K[1, 2]) / K[1, 1], 1.0])
    centre = T[:3, :3] @ (z * ray) + T[:3, 3]  # what the pixel next to the image centre sees
    assert np.linalg.norm(centre[:2] - TARGET[:2]) < 0.05
    assert truth.distance(centre[None])[0] < 1e-6  # ... lies on the true surface


def test_empty_plan_is_refused(tmp_path):
    model = small_model()
    plan = ScanPlan(TARGET, 0.4, 0.06, ViewLayout("ring", 1, 1), 55.0, np.zeros(6), [], [])
    with pytest.raises(ConfigError, match="no viewpoint"):
        record_mock_scan(tmp_path / "x.mcap", plan, model)
