"""Input checks: frames, emptiness, size, units, file kinds."""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np
import pytest

from armstereo.errors import ConfigError, RecordingError
from armstereo.io.ply import write_ply
from armstereo.recording import RecordingWriter
from armstereo.scene import SceneCloud, check_cloud, load_cloud
from armstereo.scene.synthetic import default_truth, scan

SAMPLE = Path(__file__).parents[3] / "recordings" / "sample.mcap"  # a capture: no /points


@pytest.fixture(scope="module")
def cloud():
    return scan(default_truth(), spacing=0.005)


def test_ply_with_base_frame_comment_loads(tmp_path, cloud):
    path = write_ply(tmp_path / "c.ply", cloud.points, cloud.colors_bgr,
                     comment="armstereo pair 0, frame base, metres")
    got = load_cloud(path)
    assert got.frame_id == "base" and np.allclose(got.points, cloud.points, atol=1e-6)
    assert np.array_equal(got.colors_bgr, cloud.colors_bgr)


def test_ply_in_another_frame_is_refused(tmp_path, cloud):
    path = write_ply(tmp_path / "c.ply", cloud.points, cloud.colors_bgr,
                     comment="frame camera_optical, metres")
    with pytest.raises(ConfigError, match="frame 'camera_optical'.*'base'"):
        load_cloud(path)


def test_ply_without_a_frame_is_taken_as_base_with_a_warning(tmp_path, cloud, caplog):
    path = write_ply(tmp_path / "c.ply", cloud.points, cloud.colors_bgr)
    with caplog.at_level(logging.WARNING):
        assert load_cloud(path).frame_id == "base"
    assert "names no frame" in caplog.text


def test_empty_tiny_and_millimetre_clouds_are_refused(cloud):
    with pytest.raises(ConfigError, match="empty"):
        check_cloud(SceneCloud(np.full((10, 3), np.nan), None, "base", "nan"))
    with pytest.raises(ConfigError, match="only 50 point"):
        check_cloud(SceneCloud(cloud.points[:50], None, "base", "tiny"))
    with pytest.raises(ConfigError, match="not in metres"):
        check_cloud(SceneCloud(cloud.points * 1000, None, "base", "mm"))


def test_non_finite_points_are_dropped_with_their_colours(cloud):
    pts = cloud.points.copy()
    pts[::7, 1] = np.inf
    got = check_cloud(SceneCloud(pts, cloud.colors_bgr, "base", "holes"))
    assert len(got.points) == len(pts) - len(pts[::7])
    assert np.array_equal(got.colors_bgr, cloud.colors_bgr[np.isfinite(pts).all(axis=1)])


def test_unknown_files_and_bad_plys_are_config_errors(tmp_path):
    with pytest.raises(ConfigError, match="no such file"):
        load_cloud(tmp_path / "missing.ply")
    (tmp_path / "x.xyz").write_text("1 2 3\n")
    with pytest.raises(ConfigError, match=r"\.ply"):
        load_cloud(tmp_path / "x.xyz")
    (tmp_path / "bad.ply").write_bytes(b"not a ply")
    with pytest.raises(ConfigError, match="not a PLY"):
        load_cloud(tmp_path / "bad.ply")


def _mcap_with_cloud(path, cloud, frame="base"):
    with RecordingWriter(path, metadata={"scene_truth": "{}"}) as w:
        w.write_point_cloud(cloud.points, cloud.colors_bgr, 123, frame_id=frame)
    return path


def test_mcap_cloud_loads_with_metadata_and_time(tmp_path, cloud):
    got = load_cloud(_mcap_with_cloud(tmp_path / "r.mcap", cloud))
    assert got.timestamp_ns == 123 and got.metadata["scene_truth"] == "{}"
    assert np.allclose(got.points, cloud.points, atol=1e-6)


def test_mcap_cloud_in_another_frame_or_without_points_is_refused(tmp_path, cloud):
    with pytest.raises(ConfigError, match="camera_optical"):
        load_cloud(_mcap_with_cloud(tmp_path / "r.mcap", cloud, frame="camera_optical"))
    with pytest.raises(RecordingError, match="no readable /points.*reconstruct"):
        load_cloud(SAMPLE)
