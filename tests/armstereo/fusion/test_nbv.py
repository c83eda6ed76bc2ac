"""Greedy next-best view: the gain counts unknown space a camera would see, and auto:N scans
choose, check and record viewpoints one at a time."""

import json
import math

import numpy as np
import pytest

from armstereo.capture.scan_plan import look_at_pose
from armstereo.errors import ConfigError
from armstereo.fusion import nbv
from armstereo.fusion.nbv import parse_auto, surface_box, target_roi, visible_unknown
from armstereo.fusion.run import FusionOptions, fuse_recording
from armstereo.fusion.tsdf import TsdfVolume
from armstereo.recording import Recording
from tests.armstereo.fusion.synthetic import ROI, SMALL, TARGET, record_small_scan, ring_frames


@pytest.mark.parametrize("text,n", [("auto:3", 3), ("AUTO:12", 12), ("ring:3", None),
                                    ("grid:2x3", None)])
def test_parse_auto(text, n):
    assert parse_auto(text) == n


@pytest.mark.parametrize("text", ["auto", "auto:0", "auto:x", "auto:51", "autox:3"])
def test_parse_auto_rejects(text):
    with pytest.raises(ConfigError, match="auto:N"):
        parse_auto(text)


def _volume():
    return TsdfVolume(target_roi(TARGET, 0.45), nbv.VOXEL_M, nbv.TRUNC_VOXELS * nbv.VOXEL_M,
                      threads=1)


def test_an_unseen_volume_is_all_gain_and_a_seen_view_has_little():
    frames, _ = ring_frames(4)
    volume = _volume()
    T0, T2 = frames[0].T_base_camera, frames[2].T_base_camera
    rays = (SMALL.width // nbv.RAY_STRIDE_PX) * (SMALL.height // nbv.RAY_STRIDE_PX)
    empty = visible_unknown(volume, T0, SMALL.K, SMALL.size)
    assert 0.9 * rays <= empty <= rays  # every ray through the target cube meets unknown space
    lo, hi = surface_box(volume)
    assert lo.tolist() == [0, 0, 0] and (hi + 1).tolist() == list(volume.shape)
    volume.integrate(frames[0])
    seen = visible_unknown(volume, T0, SMALL.K, SMALL.size)
    other = visible_unknown(volume, T2, SMALL.K, SMALL.size)  # the opposite side of the ring
    assert seen < 0.1 * empty and other > 3 * seen
    volume.integrate(frames[2])
    assert visible_unknown(volume, T2, SMALL.K, SMALL.size) < 0.5 * other


def test_the_gain_is_counted_around_the_surfaces_seen():
    frames, _ = ring_frames(4)
    volume = _volume()
    volume.integrate(frames[0])
    lo, hi = surface_box(volume)
    z_lo, z_hi = volume.origin[2] + lo[2] * volume.voxel, volume.origin[2] + hi[2] * volume.voxel
    # the table (z = 0) to the top of the tallest object (0.15 m), grown by 2 cm
    assert -0.05 < z_lo < -0.005 and 0.15 < z_hi < 0.2
    above = look_at_pose(TARGET + [0, 0, 0.6], 0.0, math.radians(89.0), 0.01)
    assert visible_unknown(volume, above, SMALL.K, SMALL.size, box=(lo, hi)) \
        <= visible_unknown(volume, above, SMALL.K, SMALL.size,
                           box=(np.zeros(3, np.int64), np.array(volume.shape) - 1))


@pytest.fixture(scope="module")
def auto_scan(tmp_path_factory):
    path = tmp_path_factory.mktemp("auto") / "auto.mcap"
    return path, record_small_scan(path, "auto:3")


def test_auto_scan_records_its_choices(auto_scan):
    path, outcome = auto_scan
    tour = outcome.tour
    rec = Recording.open(path)
    chosen = [c["viewpoint"] for c in tour.chosen]
    assert len(rec) == len(chosen) == 3 and len(set(chosen)) == 3
    assert [p.viewpoint for p in rec] == chosen
    candidates = [m["viewpoint"] for m in json.loads(rec.metadata["scan_viewpoints"])]
    assert len(candidates) == nbv.CANDIDATES_MIN and set(chosen) <= set(candidates)
    assert rec.metadata["views"] == "auto:3" and rec.metadata["pairs"] == "3"
    assert tour.stop_reason == "budget of 3 viewpoints spent"
    gains = [c["gain_rays"] for c in tour.chosen]
    assert gains[0] == max(gains) and all(g > 0 for g in gains)
    assert rec.warnings == []


def test_auto_scan_fuses(auto_scan, tmp_path):
    path, _ = auto_scan
    report = fuse_recording(path, tmp_path, FusionOptions(voxel=0.006, roi=ROI, workers=1))
    assert report["views"] == 3 and report["accuracy"]["accuracy_mean_mm"] < 2.0


def test_auto_stops_when_the_gain_is_small(tmp_path, monkeypatch):
    monkeypatch.setattr(nbv, "MIN_GAIN_SHARE", 1.01)  # nothing after the first view is enough
    outcome = record_small_scan(tmp_path / "a.mcap", "auto:3")
    assert len(outcome.result.pairs) == 1
    assert outcome.tour.stop_reason.startswith("best gain")


def test_a_failing_direct_move_goes_by_way_of_the_start(tmp_path, monkeypatch):
    monkeypatch.setattr(nbv.AutoTour, "_direct_ok", lambda self, a, b: False)
    outcome = record_small_scan(tmp_path / "a.mcap", "auto:2")
    assert len(outcome.result.pairs) == 2 and outcome.tour.detours == 1
