"""Damaged recordings: truncated, corrupted, foreign, killed writers. Only RecordingError."""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import textwrap

import cv2
import numpy as np
import pytest
from foxglove_schemas_protobuf.CameraCalibration_pb2 import CameraCalibration
from foxglove_schemas_protobuf.CompressedImage_pb2 import CompressedImage
from foxglove_schemas_protobuf.FrameTransform_pb2 import FrameTransform
from foxglove_schemas_protobuf.FrameTransforms_pb2 import FrameTransforms
from foxglove_schemas_protobuf.Log_pb2 import Log
from foxglove_schemas_protobuf.Quaternion_pb2 import Quaternion
from foxglove_schemas_protobuf.Vector3_pb2 import Vector3
from mcap.reader import make_reader
from mcap.writer import CompressionType
from mcap.writer import Writer as McapWriter
from mcap_protobuf.schema import register_schema

from armstereo.errors import RecordingError
from armstereo.recording import Recording
from tests.support import ROOT
from tests.support.recordings import assert_view_matches, write_synthetic

N_VIEWS = 5


@pytest.fixture(scope="module")
def original(tmp_path_factory):
    """A finished 5-view recording: (bytes, views written)."""
    path = tmp_path_factory.mktemp("orig") / "orig.mcap"
    views = write_synthetic(path, N_VIEWS)
    return path.read_bytes(), views


def read_everything(path) -> Recording:
    """Open and touch every decoded value, as reconstruction would."""
    rec = Recording.open(path)
    for view in rec.views:
        view.image, view.depth  # noqa: B018 - decoding is the point
    if rec.calibration is not None:
        for pair in rec:
            pair.left.image, pair.right.image  # noqa: B018
    return rec


def test_truncation_at_many_offsets_recovers_more_views_as_more_bytes_remain(tmp_path,
                                                                             original):
    data, views = original
    counts = []
    for cut in np.linspace(0, len(data), 41).astype(int):
        path = tmp_path / "cut.mcap"
        path.write_bytes(data[:cut])
        try:
            rec = read_everything(path)
        except RecordingError as err:
            assert cut < 8, f"cut at {cut}: {err}"  # only a missing magic is fatal
            counts.append(0)
            continue
        counts.append(len(rec.views))
        for view in rec.views:
            assert_view_matches(view, views[view.index])
        if cut < len(data):
            assert rec.truncated and rec.lost and not rec.indexed
    assert counts == sorted(counts), counts
    assert counts[-1] == N_VIEWS and counts[-2] == N_VIEWS  # summary lost, all data kept
    assert 0 < counts[len(counts) // 2] < N_VIEWS


def test_random_corruption_yields_only_recording_errors_or_warnings(tmp_path, original):
    data, views = original
    rng = np.random.default_rng(1234)
    outcomes = {"error": 0, "warned": 0, "clean": 0}
    for trial in range(60):
        damaged = bytearray(data)
        for pos in rng.integers(8, len(data) - 8, rng.integers(1, 6)):
            damaged[pos] = rng.integers(0, 256)
        path = tmp_path / f"bad{trial}.mcap"
        path.write_bytes(bytes(damaged))
        try:
            rec = read_everything(path)
        except RecordingError:
            outcomes["error"] += 1
            continue
        outcomes["warned" if rec.warnings else "clean"] += 1
        for view in rec.views:  # whatever survives is exactly what was written
            assert_view_matches(view, views[view.index])
    assert outcomes["warned"] > 0, outcomes


def test_corrupted_chunk_in_an_indexed_file_loses_only_that_chunk(tmp_path, original):
    data, views = original
    with open(tmp_path / "o.mcap", "wb") as f:
        f.write(data)
    with open(tmp_path / "o.mcap", "rb") as f:
        chunks = make_reader(f).get_summary().chunk_indexes
    t2 = views[2]["frame"].timestamp_ns
    hit = next(c for c in chunks if c.message_start_time == t2 and c.chunk_length > 1000)
    damaged = bytearray(data)
    damaged[hit.chunk_start_offset + hit.chunk_length // 2] ^= 0xFF
    path = tmp_path / "chunk.mcap"
    path.write_bytes(bytes(damaged))
    rec = read_everything(path)
    assert rec.indexed and not rec.truncated
    assert any(f"chunk at byte {hit.chunk_start_offset}" in text for text in rec.lost)
    assert [v.index for v in rec.views] == [0, 1, 3, 4]  # views after the damage survive
    assert [p.index for p in rec.pairs] == [0, 3]  # pairs 1 and 2 need view 2


def test_garbage_and_hostile_lengths_are_recording_errors(tmp_path):
    rng = np.random.default_rng(7)
    magic = b"\x89MCAP0\r\n"
    cases = [
        b"\x00",
        magic,
        magic + b"\x01" + (2**63).to_bytes(8, "little"),  # header claiming 8 EiB
        magic + bytes(rng.integers(0, 256, 3000, dtype=np.uint8)),
        magic + b"\x06" + (200).to_bytes(8, "little") + b"\xff" * 200 + magic,
    ]
    for k, blob in enumerate(cases):
        path = tmp_path / f"g{k}.mcap"
        path.write_bytes(blob)
        try:
            rec = read_everything(path)
        except RecordingError as err:
            assert "\n" not in str(err)
        else:
            assert rec.warnings and len(rec.views) == 0


def _foreign(path, png: bytes | None = None) -> None:
    """Our topics written by plain mcap (unchunked), plus channels armstereo does not know."""
    with open(path, "wb") as f:
        w = McapWriter(f, use_chunking=False, compression=CompressionType.NONE)
        w.start()
        ids = {}
        for topic, cls in (("/camera/image", CompressedImage), ("/tf", FrameTransforms),
                           ("/camera/calibration", CameraCalibration), ("/rosout", Log)):
            ids[topic] = w.register_channel(topic, "protobuf", register_schema(w, cls))
        sid = w.register_schema("armstereo.CaptureEvent", "jsonschema", b"{}")
        ids["/capture/events"] = w.register_channel("/capture/events", "json", sid)
        ids["/diagnostics"] = w.register_channel("/diagnostics", "json", 0)
        K = [50.0, 0, 15.5, 0, 50.0, 11.5, 0, 0, 1]
        cal = CameraCalibration(width=32, height=24, K=K, D=[0] * 5, frame_id="camera_optical")
        w.add_message(ids["/camera/calibration"], 0, cal.SerializeToString(), 0)
        if png is None:
            png = cv2.imencode(".png", np.full((24, 32), 128, np.uint8))[1].tobytes()
        for view, t in enumerate((10, 20)):
            tf = FrameTransforms(transforms=[
                FrameTransform(parent_frame_id="base", child_frame_id="tool0",
                               translation=Vector3(x=0.1 * view), rotation=Quaternion(w=1)),
                FrameTransform(parent_frame_id="tool0", child_frame_id="camera_optical",
                               rotation=Quaternion(w=1))])
            img = CompressedImage(format="png", data=png, frame_id="camera_optical")
            event = {"event": "view", "view": view, "timestamp_ns": t, "settle_s": 0}
            for topic, payload in (("/camera/image", img.SerializeToString()),
                                   ("/tf", tf.SerializeToString()),
                                   ("/capture/events", json.dumps(event).encode()),
                                   ("/rosout", Log(message="hi").SerializeToString()),
                                   ("/diagnostics", b'{"ok": true}')):
                w.add_message(ids[topic], t, payload, t)
        pair = {"event": "pair", "pair": 0, "left_view": 0, "right_view": 1,
                "commanded_baseline_m": 0.1, "achieved_baseline_m": 0.1, "direction": "x"}
        w.add_message(ids["/capture/events"], 20, json.dumps(pair).encode(), 20)
        w.finish()


def test_foreign_mcap_with_unknown_channels_warns_once_per_topic_and_reads(tmp_path):
    path = tmp_path / "foreign.mcap"
    _foreign(path)
    rec = read_everything(path)
    assert "ignored 2 message(s) on unknown topic /rosout" in rec.warnings
    assert "ignored 2 message(s) on unknown topic /diagnostics" in rec.warnings
    assert sum("/rosout" in w for w in rec.warnings) == 1
    assert len(rec) == 1 and rec[0].left.image.shape == (24, 32)
    assert np.allclose(rec[0].right.T_base_camera[:3, 3], [0.1, 0, 0])
    assert any("joint states" in w for w in rec.warnings)  # optional, so only a warning


def test_image_bombs_and_undecodable_images_are_recording_errors(tmp_path):
    png = cv2.imencode(".png", np.full((24, 32), 128, np.uint8))[1].tobytes()
    bomb = png[:16] + (60000).to_bytes(4, "big") * 2 + png[24:]  # IHDR claims 60000 x 60000
    for blob, match in ((bomb, "header claims 60000x60000"), (png[:40], "could not be decoded")):
        path = tmp_path / "bomb.mcap"
        _foreign(path, png=blob)
        rec = Recording.open(path)
        with pytest.raises(RecordingError, match=match):
            rec[0].left.image  # noqa: B018


WRITER_LOOP = textwrap.dedent("""
    import signal, sys, time
    # Ctrl-C handled as Python does by default, even when the test runner started with SIGINT
    # ignored (nohup, background jobs): a child inherits an ignored signal.
    signal.signal(signal.SIGINT, signal.default_int_handler)
    sys.path.insert(0, sys.argv[2])
    from tests.support.recordings import JOINTS, small_intrinsics, synthetic_views
    from armstereo.recording import RecordingWriter
    intr = small_intrinsics()
    views = synthetic_views(200, intr, depth=False)
    try:
        with RecordingWriter(sys.argv[1], metadata={"robot": "ur5e"}) as w:
            w.write_calibration(intr, views[0]["frame"].timestamp_ns - 1)
            for v in views:
                w.write_view(v["view"], v["frame"], v["q"], JOINTS, v["T_base_flange"],
                             v["T_flange_camera"], settle_s=0.0)
                if v["view"]:
                    w.write_pair(v["view"] - 1, v["view"] - 1, v["view"], 0.05, 0.05, "x")
                print(v["view"] + 1, flush=True)
                time.sleep(0.02)
    except KeyboardInterrupt:
        print("interrupted", flush=True)
""")


def _run_writer_until(path, views: int, sig: int) -> tuple[int, str]:
    """Start a writing process, send ``sig`` after it reports ``views`` flushed views."""
    root = ROOT
    proc = subprocess.Popen([sys.executable, "-c", WRITER_LOOP, str(path), str(root)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    reported = 0
    try:
        for line in proc.stdout:
            reported = int(line)
            if reported >= views:
                proc.send_signal(sig)
                break
        rest, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert reported >= views, err
    return reported, rest


def test_sigkill_leaves_every_reported_view_readable(tmp_path):
    path = tmp_path / "killed.mcap"
    reported, _ = _run_writer_until(path, 4, signal.SIGKILL)
    rec = read_everything(path)
    assert rec.truncated and not rec.indexed
    assert any("no index" in w for w in rec.warnings)
    assert len(rec.views) >= reported
    assert len(rec) >= reported - 1 and rec.metadata["robot"] == "ur5e"


def test_sigint_finishes_the_file_cleanly(tmp_path):
    path = tmp_path / "interrupted.mcap"
    reported, rest = _run_writer_until(path, 3, signal.SIGINT)
    assert "interrupted" in rest
    rec = read_everything(path)
    assert rec.indexed and not rec.truncated and rec.warnings == []
    assert len(rec.views) >= reported
