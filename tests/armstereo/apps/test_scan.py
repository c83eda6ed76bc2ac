"""record_scan (what armstereo scan runs) on the mock: one pair per viewpoint tagged with it,
poses from the arm, capture's metadata and truth; refusals move nothing; a fault keeps every
complete pair and fuse works on them."""

import json

import numpy as np
import pytest

from armstereo.apps.scan import ScanRequest, record_scan
from armstereo.capture.plan import Workspace
from armstereo.errors import ConnectionLost, PreflightError, UserAbort
from armstereo.evaluation.scene_truth import SceneTruth
from armstereo.fusion.run import FusionOptions, fuse_recording
from armstereo.recording import Recording
from tests.armstereo.fusion.synthetic import ROI, TARGET, record_small_scan, small_model


@pytest.fixture(scope="module")
def scan(tmp_path_factory):
    path = tmp_path_factory.mktemp("scan") / "scan.mcap"
    outcome = record_small_scan(path, "ring:3", camera_noise=0.0)
    return outcome, Recording.open(path)


def test_one_pair_per_viewpoint_in_tour_order(scan):
    outcome, rec = scan
    views = outcome.tour.scan.views
    assert len(outcome.result.pairs) == len(rec) == len(views) == 3
    assert rec.warnings == [] and len(rec.views) == 6
    assert [p.viewpoint for p in rec] == [v.index for v in views]
    assert [p.viewpoint for p in outcome.result.pairs] == [v.index for v in views]
    meta = json.loads(rec.metadata["scan_viewpoints"])
    assert [m["viewpoint"] for m in meta] == [v.index for v in views]
    for pair, view in zip(rec, views, strict=True):
        assert (pair.left.index, pair.right.index) == (2 * pair.index, 2 * pair.index + 1)
        np.testing.assert_allclose(pair.left.T_base_camera, view.T_base_left, atol=1e-6)
        np.testing.assert_allclose(pair.right.T_base_camera, view.T_base_right, atol=1e-6)
        assert pair.achieved_baseline_m == pytest.approx(0.06, abs=1e-6)
        assert pair.direction == "x"


def test_metadata_is_capture_s_plus_the_scan(scan):
    _, rec = scan
    meta = rec.metadata
    for key in ("robot", "urdf_sha256", "mount", "mount_toml", "kinematics_source", "dh_table",
                "dh_sha256", "ur_calibration_hash", "calibration_status", "kinematics_warnings",
                "arm", "camera", "camera_noise", "mock_profile", "scene_truth"):
        assert key in meta, key
    assert meta["kinematics_source"] == "nominal" and meta["arm"] == "mock"
    assert meta["kind"] == "scan" and meta["views"] == "ring:3" and meta["pairs"] == "3"
    assert [float(v) for v in meta["target_m"].split(",")] == pytest.approx(list(TARGET))
    assert float(meta["baseline_m"]) == 0.06 and meta["direction"] == "x"


def test_views_look_at_the_target_and_carry_ground_truth(scan):
    _, rec = scan
    truth = SceneTruth.from_json(rec.metadata["scene_truth"])
    view = rec[0].left
    assert view.depth is not None and np.isfinite(view.depth).mean() > 0.99
    T, K, z = view.T_base_camera, view.intrinsics.K, float(view.depth[120, 160])
    ray = np.array([(160 - K[0, 2]) / K[0, 0], (120 - K[1, 2]) / K[1, 1], 1.0])
    centre = T[:3, :3] @ (z * ray) + T[:3, 3]  # what the pixel next to the image centre sees
    assert np.linalg.norm(centre[:2] - TARGET[:2]) < 0.05
    assert truth.distance(centre[None])[0] < 1e-6  # ... lies on the true surface


def test_dry_run_plans_and_records_nothing(tmp_path):
    out = tmp_path / "dry.mcap"
    shown = []
    outcome = record_scan(out, ScanRequest(target=tuple(TARGET), views="ring:2"), small_model(),
                          dry_run=True, show=shown.append, progress=None)
    assert outcome.result is None and shown == [outcome.tour] and outcome.tour.ok
    assert not out.exists()


def test_unreachable_target_is_refused_before_anything_moves(tmp_path):
    out = tmp_path / "far.mcap"
    with pytest.raises(PreflightError, match="'viewpoints' failed: none of the 4 viewpoints.*"
                       "nothing moved"):
        record_scan(out, ScanRequest(target=(2.5, 0.0, 0.0), views="ring:4"), small_model(),
                    progress=None)
    assert not out.exists()


def test_a_tour_leaving_the_workspace_between_viewpoints_is_refused(tmp_path, monkeypatch):
    moves = _count_moves(monkeypatch)
    out = tmp_path / "box.mcap"
    box = Workspace.parse("-0.46,0.85,-0.85,0.85,0.05,0.85")  # see test_tour.py
    with pytest.raises(PreflightError, match="'workspace' failed.*viewpoint . -> viewpoint"):
        record_scan(out, ScanRequest(target=tuple(TARGET), views="ring:4", workspace=box),
                    small_model(), progress=None)
    assert not out.exists() and moves == []


def test_live_arm_needs_confirmation(tmp_path, monkeypatch):
    # The confirmation comes after planning and before the camera or any motion: check it on
    # the mock by letting it pretend to be live.
    import armstereo.apps.scan as app

    original = app.confirm_live_motion
    monkeypatch.setattr(app, "confirm_live_motion",
                        lambda *, live, yes, ask: original(live=True, yes=yes, ask=ask))
    moves = _count_moves(monkeypatch)
    out = tmp_path / "live.mcap"
    with pytest.raises(UserAbort, match="--yes"):
        record_scan(out, ScanRequest(target=tuple(TARGET), views="ring:2"), small_model(),
                    progress=None)
    assert not out.exists() and moves == []


def _count_moves(monkeypatch) -> list:
    """Every move the mock arm is asked for, and every stop, in order."""
    from drivers.mock.arm import MockArm

    calls = []
    for name in ("move_joints", "move_linear", "stop"):
        original = getattr(MockArm, name)

        def spy(self, *args, _name=name, _original=original, **kwargs):
            calls.append(_name)
            return _original(self, *args, **kwargs)

        monkeypatch.setattr(MockArm, name, spy)
    return calls


def test_a_fault_mid_scan_stops_the_arm_keeps_complete_pairs_and_fuses(tmp_path, monkeypatch):
    calls = _count_moves(monkeypatch)
    out = tmp_path / "cut.mcap"
    # Moves: 1 joints -> viewpoint A, 2 baseline, 3 joints -> B, 4 baseline, 5 joints -> C:
    # the link drops during move 5, after two complete pairs.
    with pytest.raises(ConnectionLost, match=r"4 view\(s\) kept"):
        record_small_scan(out, "ring:3", faults=("disconnect@5",))
    assert calls[:5] == ["move_joints", "move_linear"] * 2 + ["move_joints"]
    assert "stop" in calls[5:]  # the arm was told to stop after the error
    rec = Recording.open(out)
    assert len(rec.views) == 4 and len(rec) == 2
    assert all(p.viewpoint is not None for p in rec)
    report = fuse_recording(out, tmp_path / "fused", FusionOptions(voxel=0.006, roi=ROI,
                                                                   workers=1))
    assert report["views"] == 2 and report["mesh"]["faces"] > 0
    assert report["accuracy"]["accuracy_mean_mm"] < 3.0
