"""Recordings read cleanly in a second, independent MCAP implementation (TypeScript @mcap/core).

Runs ``tests/ts_reader/check.mjs`` under node; its npm packages are installed on first use into
``tests/ts_reader/node_modules`` (git-ignored).
"""

from __future__ import annotations

import json
import shutil
import subprocess

import numpy as np
import pytest
from foxglove_schemas_protobuf.FrameTransform_pb2 import FrameTransform
from foxglove_schemas_protobuf.FrameTransforms_pb2 import FrameTransforms
from foxglove_schemas_protobuf.Quaternion_pb2 import Quaternion
from google.protobuf.timestamp_pb2 import Timestamp
from mcap.writer import Writer as McapWriter
from mcap_protobuf.schema import register_schema

from armstereo.recording import RecordingWriter
from armstereo.recording import schemas as S
from tests.support import ROOT, SAMPLE_RECORDING
from tests.support.recordings import (
    JOINTS,
    small_intrinsics,
    synthetic_views,
    write_synthetic,
)

# node + npm install on first use.
pytestmark = pytest.mark.slow

TS_DIR = ROOT / "tests" / "ts_reader"
SAMPLE = SAMPLE_RECORDING
ALL_TOPICS = (S.TOPIC_IMAGE, S.TOPIC_CALIBRATION, S.TOPIC_TF, S.TOPIC_JOINT_STATES,
              S.TOPIC_EVENTS, S.TOPIC_DEPTH, S.TOPIC_POINTS)


def _installed() -> bool:
    deps = json.loads((TS_DIR / "package.json").read_text())["dependencies"]
    return all((TS_DIR / "node_modules" / name / "package.json").exists() for name in deps)


@pytest.fixture(scope="module")
def ts_check():
    """Function running check.mjs on files: returns the CompletedProcess."""
    node, npm = shutil.which("node"), shutil.which("npm")
    if not (node and npm):
        pytest.skip("node/npm not installed")
    if not _installed():
        done = subprocess.run([npm, "install", "--no-audit", "--no-fund"], cwd=TS_DIR,
                              capture_output=True, text=True, timeout=600)
        assert done.returncode == 0, f"npm install failed: {done.stderr[-2000:]}"

    def run(*args):
        return subprocess.run([node, "check.mjs", *map(str, args)], cwd=TS_DIR,
                              capture_output=True, text=True, timeout=300)

    return run


def test_every_channel_decodes_in_the_typescript_reader(tmp_path, ts_check):
    png, jpeg = tmp_path / "png.mcap", tmp_path / "jpeg.mcap"
    write_synthetic(png, 3, point_cloud=True)
    write_synthetic(jpeg, 2, image_format="jpeg",
                    intr=small_intrinsics(dist=np.array([0.1, -0.2, 0, 0, 0.01, 0, 0, 0])))
    done = ts_check(png, jpeg)
    assert done.returncode == 0, done.stdout + done.stderr
    for topic in ALL_TOPICS:
        assert f"  {topic}  " in done.stdout
    assert "3 messages decoded" in done.stdout and done.stdout.count("  OK") == 2


def test_an_unfinished_recording_streams_in_the_typescript_reader(tmp_path, ts_check):
    path, killed = tmp_path / "live.mcap", tmp_path / "killed.mcap"
    intr = small_intrinsics()
    with RecordingWriter(path, metadata={}) as w:
        w.write_calibration(intr, 0)
        for v in synthetic_views(2, intr):
            w.write_view(v["view"], v["frame"], v["q"], JOINTS, v["T_base_flange"],
                         v["T_flange_camera"], settle_s=0.5)
        killed.write_bytes(path.read_bytes())  # what SIGKILL would leave: no summary, no footer
    strict = ts_check(killed)
    assert strict.returncode == 1 and "McapIndexedReader" in strict.stdout
    lenient = ts_check("--allow-unindexed", killed)
    assert lenient.returncode == 0, lenient.stdout
    assert "/camera/image  foxglove.CompressedImage  protobuf  2 messages" in lenient.stdout


def test_the_checker_flags_bad_quaternions_and_unpublished_schemas(tmp_path, ts_check):
    path = tmp_path / "planted.mcap"
    with open(path, "wb") as f:
        w = McapWriter(f)
        w.start()
        tf = w.register_channel("/tf", "protobuf", register_schema(w, FrameTransforms))
        ts = w.register_channel("/clock", "protobuf", register_schema(w, Timestamp))
        bad = FrameTransforms(transforms=[FrameTransform(parent_frame_id="base",
                                                         child_frame_id="tool0",
                                                         rotation=Quaternion(w=2.0))])
        w.add_message(tf, 1, bad.SerializeToString(), 1)
        w.add_message(ts, 1, Timestamp(seconds=1).SerializeToString(), 1)
        w.finish()
    done = ts_check(path)
    assert done.returncode == 1
    assert "quaternion norm 2" in done.stdout
    assert "google.protobuf.Timestamp is not a published foxglove schema" in done.stdout
    assert '0 "armstereo" metadata records' in done.stdout


def test_the_sample_recording_reads_in_the_typescript_reader(ts_check):
    done = ts_check(SAMPLE)
    assert done.returncode == 0, done.stdout + done.stderr
    assert "  OK" in done.stdout
