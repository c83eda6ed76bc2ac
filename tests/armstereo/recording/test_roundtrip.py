"""Recordings: write then read back bit for bit (images, depth) and pose for pose."""

from __future__ import annotations

import os
import signal

import numpy as np
import pytest

from armstereo.devices import Frame
from armstereo.errors import ConfigError, RecordingError
from armstereo.recording import Recording, RecordingWriter
from armstereo.recording import schemas as S
from armstereo.recording.crash_safe import signals_deferred as _signals_deferred
from tests.support.recordings import (
    BASELINE,
    JOINTS,
    T0_NS,
    assert_view_matches,
    small_intrinsics,
    synthetic_views,
    write_synthetic,
)


def test_round_trip_is_bit_exact_for_images_and_depth_and_exact_for_poses(tmp_path):
    path = tmp_path / "r.mcap"
    intr = small_intrinsics()
    views = write_synthetic(path, 4, intr=intr)
    rec = Recording.open(path)
    assert rec.indexed and not rec.truncated
    assert rec.warnings == [] and rec.lost == []
    assert len(rec) == 3 and len(rec.views) == 4
    for k, pair in enumerate(rec):
        assert pair.index == k and (pair.left.index, pair.right.index) == (k, k + 1)
        assert pair.commanded_baseline_m == BASELINE and pair.direction == "x"
        assert_view_matches(pair.left, views[k])
        assert_view_matches(pair.right, views[k + 1])
        assert np.array_equal(pair.left.intrinsics.K, intr.K)
        assert pair.left.joint_names == JOINTS and pair.left.settle_s == 0.5
    assert rec[2].right.index == 3 and rec.view(0).index == 0
    assert rec.metadata["robot"] == "ur5e" and rec.metadata["mount_toml"].endswith("[x]\n")
    assert rec.metadata["format_version"] == S.FORMAT_VERSION
    assert rec.duration_s == pytest.approx((views[-1]["frame"].timestamp_ns - T0_NS + 1000) / 1e9)


def test_channels_use_the_documented_topics_and_schemas(tmp_path):
    path = tmp_path / "r.mcap"
    write_synthetic(path, 2)
    rec = Recording.open(path)
    got = {c.topic: (c.schema, c.encoding, c.messages) for c in rec.channels}
    assert got == {
        S.TOPIC_CALIBRATION: ("foxglove.CameraCalibration", "protobuf", 1),
        S.TOPIC_IMAGE: ("foxglove.CompressedImage", "protobuf", 2),
        S.TOPIC_DEPTH: ("foxglove.RawImage", "protobuf", 2),
        S.TOPIC_TF: ("foxglove.FrameTransforms", "protobuf", 2),
        S.TOPIC_JOINT_STATES: ("armstereo.JointStates", "json", 2),
        S.TOPIC_EVENTS: ("armstereo.CaptureEvent", "json", 3),
    }


def test_calibration_round_trip_and_distortion_models(tmp_path):
    for dist, model in ([np.array([0.1, -0.2, 1e-3, 2e-3, 0.05]), "plumb_bob"],
                        [np.array([0.1, -0.2, 1e-3, 2e-3, 0.05, 0.01, 0.02, 0.03]),
                         "rational_polynomial"]):
        path = tmp_path / f"{model}.mcap"
        intr = small_intrinsics(dist=dist)
        write_synthetic(path, 2, intr=intr)
        rec = Recording.open(path)
        assert rec.calibration_info["distortion_model"] == model
        assert rec.calibration_info["frame_id"] == S.FRAME_CAMERA
        assert np.array_equal(rec.calibration.K, intr.K)
        assert np.array_equal(rec.calibration.dist, dist)
        assert rec.calibration.size == (48, 32)
    path = tmp_path / "four.mcap"
    write_synthetic(path, 2, intr=small_intrinsics(dist=np.array([0.1, -0.2, 0.0, 0.0])))
    assert np.array_equal(Recording.open(path).calibration.dist, [0.1, -0.2, 0.0, 0.0, 0.0])


def test_jpeg_option_decodes_close_to_the_original(tmp_path):
    path = tmp_path / "j.mcap"
    intr = small_intrinsics(64, 48)
    views = synthetic_views(2, intr)
    smooth = np.repeat(np.linspace(0, 255, 64, dtype=np.uint8)[None, :, None], 48, axis=0)
    with RecordingWriter(path, metadata={}, image_format="jpeg") as w:
        w.write_calibration(intr, T0_NS)
        for v in views:
            frame = Frame(np.repeat(smooth, 3, axis=2), v["frame"].timestamp_ns)
            w.write_view(v["view"], frame, v["q"], JOINTS, v["T_base_flange"],
                         v["T_flange_camera"], settle_s=0.1)
        w.write_pair(0, 0, 1, 0.05, 0.05, "x")
    rec = Recording.open(path)
    img = rec[0].left.image
    assert rec[0].left.image_format == "jpeg" and rec[0].left.image_size == (64, 48)
    assert img.shape == (48, 64, 3) and img.dtype == np.uint8
    assert np.abs(img.astype(int) - np.repeat(smooth, 3, axis=2)).mean() < 2.0
    assert rec[0].left.depth is None


def test_grey_images_and_point_clouds_round_trip(tmp_path):
    path = tmp_path / "g.mcap"
    intr = small_intrinsics()
    rng = np.random.default_rng(3)
    grey = rng.integers(0, 256, (32, 48), dtype=np.uint8)
    pts = rng.normal(size=(100, 3))
    cols = rng.integers(0, 256, (100, 3), dtype=np.uint8)
    with RecordingWriter(path, metadata={}) as w:
        w.write_calibration(intr, T0_NS)
        w.write_view(0, Frame(grey, T0_NS + 1), np.zeros(6), JOINTS, np.eye(4), np.eye(4),
                     settle_s=0.0)
        w.write_point_cloud(pts, cols, T0_NS + 5)
    rec = Recording.open(path)
    assert np.array_equal(rec.view(0).image, grey)
    (cloud,) = rec.point_clouds
    assert cloud.frame_id == "base" and cloud.timestamp_ns == T0_NS + 5
    assert np.array_equal(cloud.points, pts.astype(np.float32).astype(float))
    assert np.array_equal(cloud.colors_bgr, cols)


def test_lower_level_writes_on_other_topics_are_reported_not_fatal(tmp_path):
    path = tmp_path / "o.mcap"
    with RecordingWriter(path, metadata={}) as w:
        w.write_calibration(small_intrinsics(), T0_NS)
        w.write_image("/rectified/left", np.zeros((32, 48, 3), np.uint8), T0_NS)
        w.write_image("/reconstruction/disparity", np.zeros((32, 48), np.uint8), T0_NS)
        w.write_depth(np.ones((32, 48), np.float32), T0_NS, topic="/reconstruction/depth")
        w.write_frames(np.eye(4), np.eye(4), T0_NS)
        w.write_depth(np.ones((32, 48), np.float32), T0_NS)
        with pytest.raises(RecordingError, match="topic /tf carries foxglove.FrameTransforms"):
            w.write_image("/tf", np.zeros((32, 48), np.uint8), T0_NS)
        with pytest.raises(RecordingError, match="carries foxglove.RawImage, not foxglove.Comp"):
            w.write_image("/reconstruction/depth", np.zeros((32, 48), np.uint8), T0_NS)
    rec = Recording.open(path)
    schemas = {c.topic: c.schema for c in rec.channels}
    assert schemas["/reconstruction/depth"] == "foxglove.RawImage"
    assert schemas["/reconstruction/disparity"] == "foxglove.CompressedImage"
    assert [w for w in rec.warnings if "/r" in w] == [
        "ignored 1 message(s) on unknown topic /rectified/left"]
    assert sum("belong to no complete view" in w for w in rec.warnings) == 2  # /tf, depth


def test_missing_calibration_warns_and_pair_access_names_it(tmp_path):
    path = tmp_path / "nocal.mcap"
    write_synthetic(path, 2, calibration=False)
    rec = Recording.open(path)
    assert any(S.TOPIC_CALIBRATION in w for w in rec.warnings)
    assert len(rec) == 1 and rec.views[0].intrinsics is None
    with pytest.raises(RecordingError, match="/camera/calibration"):
        rec[0]
    with pytest.raises(RecordingError, match="intrinsics"):
        list(rec)


def test_no_complete_pair_opens_but_require_pairs_refuses(tmp_path):
    path = tmp_path / "nopair.mcap"
    write_synthetic(path, 1, pairs=False)
    rec = Recording.open(path)
    assert len(rec) == 0 and len(rec.views) == 1
    with pytest.raises(RecordingError, match="no complete stereo pair"):
        rec.require_pairs()


def test_inconsistent_baseline_is_reported(tmp_path):
    path = tmp_path / "bad.mcap"
    intr = small_intrinsics()
    views = synthetic_views(2, intr)
    with RecordingWriter(path, metadata={}) as w:
        w.write_calibration(intr, T0_NS)
        for v in views:
            w.write_view(v["view"], v["frame"], v["q"], JOINTS, v["T_base_flange"],
                         v["T_flange_camera"], settle_s=0.5)
        w.write_pair(0, 0, 1, BASELINE, BASELINE + 0.0002, "x")
    rec = Recording.open(path)
    (warning,) = rec.warnings
    assert "pair 0" in warning and "50.200 mm in the event" in warning and "50.000 mm" in warning


@pytest.mark.parametrize(("call", "match"), [
    (lambda w, v: w.write_view(0, v["frame"], v["q"], JOINTS, v["T_base_flange"],
                               v["T_flange_camera"], settle_s=0.5), "already written"),
    (lambda w, v: w.write_view(1, v["frame"], v["q"], JOINTS, v["T_base_flange"],
                               v["T_flange_camera"], settle_s=0.5), "same timestamp"),
    (lambda w, v: w.write_pair(0, 0, 7, 0.1, 0.1, "x"), "right_view 7 was not written"),
    (lambda w, v: w.write_view(2, Frame(v["frame"].image.astype(float), 5), v["q"], JOINTS,
                               np.eye(4), np.eye(4), settle_s=0.5), "uint8"),
    (lambda w, v: w.write_view(2, Frame(v["frame"].image, 5), v["q"][:5], JOINTS,
                               np.eye(4), np.eye(4), settle_s=0.5), "5 joint positions"),
    (lambda w, v: w.write_view(2, Frame(v["frame"].image, 5), v["q"], JOINTS,
                               np.diag([1.0, 1.0, 2.0, 1.0]), np.eye(4), settle_s=0.5),
     "T_base_flange is not a rigid transform"),
    (lambda w, v: w.write_calibration(small_intrinsics(), 1.5), "integer nanoseconds"),
    (lambda w, v: w.write_view(2, Frame(v["frame"].image, 5, np.zeros((3, 4), np.float32)),
                               v["q"], JOINTS, np.eye(4), np.eye(4), settle_s=0.5), "depth is"),
    (lambda w, v: w.write_view(2, Frame(v["frame"].image[:20], 5), v["q"], JOINTS, np.eye(4),
                               np.eye(4), settle_s=0.5), "48x20 but the calibration says 48x32"),
])
def test_writer_refuses_bad_input_and_writes_nothing_for_it(tmp_path, call, match):
    path = tmp_path / "w.mcap"
    v = synthetic_views(1, small_intrinsics())[0]
    with RecordingWriter(path, metadata={}) as w:
        w.write_calibration(small_intrinsics(), 0)
        w.write_view(0, v["frame"], v["q"], JOINTS, v["T_base_flange"], v["T_flange_camera"],
                     settle_s=0.5)
        with pytest.raises(RecordingError, match=match):
            call(w, v)
        assert w.views_written == 1
    rec = Recording.open(path)
    assert len(rec.views) == 1 and rec.warnings == []


def test_writer_options_and_life_cycle(tmp_path):
    with pytest.raises(ConfigError, match="webp"):
        RecordingWriter(tmp_path / "a.mcap", metadata={}, image_format="webp")
    with pytest.raises(RecordingError, match="str to str"):
        RecordingWriter(tmp_path / "b.mcap", metadata={"pairs": 3})
    with pytest.raises(RecordingError, match="cannot create"):
        RecordingWriter(tmp_path / "missing" / "c.mcap", metadata={})
    w = RecordingWriter(tmp_path / "d.mcap", metadata={}, fsync=True)
    w.flush()
    w.close()
    w.close()
    assert w.closed
    with pytest.raises(RecordingError, match="closed"):
        w.write_calibration(small_intrinsics(), 0)
    assert Recording.open(tmp_path / "d.mcap").indexed


def test_a_failed_write_leaves_the_file_readable_up_to_the_last_view(tmp_path):
    path = tmp_path / "full.mcap"
    views = synthetic_views(3, small_intrinsics())
    w = RecordingWriter(path, metadata={})
    for v in views[:2]:
        w.write_view(v["view"], v["frame"], v["q"], JOINTS, v["T_base_flange"],
                     v["T_flange_camera"], settle_s=0.5)

    def disk_full():  # half a record reaches the file, then the disk is full
        w._file.write(b"\x06\xff\xff")
        raise OSError(28, "No space left on device")

    w._mcap.flush = disk_full
    v = views[2]
    with pytest.raises(RecordingError, match="No space left"):
        w.write_view(2, v["frame"], v["q"], JOINTS, v["T_base_flange"], v["T_flange_camera"],
                     settle_s=0.5)
    with pytest.raises(RecordingError, match="failed earlier"):
        w.write_pair(0, 0, 1, 0.05, 0.05, "x")
    w.close()
    rec = Recording.open(path)
    assert [v.index for v in rec.views] == [0, 1] and rec.truncated and not rec.indexed
    assert_view_matches(rec.views[1], views[1])


def test_a_failed_finish_still_leaves_every_view_readable(tmp_path):
    path = tmp_path / "full.mcap"
    views = synthetic_views(2, small_intrinsics())
    w = RecordingWriter(path, metadata={})
    for v in views:
        w.write_view(v["view"], v["frame"], v["q"], JOINTS, v["T_base_flange"],
                     v["T_flange_camera"], settle_s=0.5)

    def disk_full():
        w._file.write(b"\x0f" + b"\x00" * 5000)  # part of the summary, then the disk is full
        raise OSError(28, "No space left on device")

    w._mcap.finish = disk_full
    with pytest.raises(RecordingError, match="finishing recording .* No space left"):
        w.close()
    rec = Recording.open(path)
    assert [v.index for v in rec.views] == [0, 1] and rec.lost[0].startswith("the file ends")


@pytest.fixture
def python_sigint():
    """Python's own Ctrl-C handler for the test, whatever pytest started with (SIGINT is
    ignored under nohup and in background jobs); the previous handler is restored after."""
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    yield
    signal.signal(signal.SIGINT, previous)


def test_signals_during_a_write_are_delivered_after_it(python_sigint):
    with pytest.raises(KeyboardInterrupt):
        with _signals_deferred():
            os.kill(os.getpid(), signal.SIGINT)
            reached = True  # the interrupt did not land inside the block
    assert reached
