"""The sample recording in recordings/ (made by ``armstereo capture`` on the mock backends) still
reads cleanly and keeps the format's promises: FK poses, mount, calibration, ground truth."""

from __future__ import annotations

import tomllib

import numpy as np

from armstereo.mount import CameraMount
from armstereo.recording import Recording
from armstereo.robot.arm_model import ArmModel
from tests.support import SAMPLE_RECORDING

SAMPLE = SAMPLE_RECORDING


def test_sample_recording_reads_cleanly_and_keeps_the_format():
    rec = Recording.open(SAMPLE)
    assert rec.indexed and not rec.truncated and rec.warnings == [] and rec.lost == []
    meta = rec.metadata
    for key in ("format_version", "armstereo_version", "robot", "urdf_sha256", "mount",
                "mount_toml", "baseline_m", "pairs"):
        assert meta.get(key), key
    mount = CameraMount.from_dict(tomllib.loads(meta["mount_toml"]), source=meta["mount_toml"])
    model = ArmModel.load(meta["robot"], mount=mount)
    assert model.urdf_sha256 == meta["urdf_sha256"]
    assert len(rec) == int(meta["pairs"]) >= 1
    for pair in rec:
        assert pair.commanded_baseline_m == float(meta["baseline_m"])
        moved = np.linalg.norm(pair.right.T_base_camera[:3, 3] - pair.left.T_base_camera[:3, 3])
        assert abs(moved - pair.achieved_baseline_m) < 1e-9
        assert abs(pair.achieved_baseline_m - pair.commanded_baseline_m) < 1e-3
        for view in (pair.left, pair.right):
            assert view.image.dtype == np.uint8
            assert view.image.shape == (mount.intrinsics.height, mount.intrinsics.width, 3)
            assert np.array_equal(view.intrinsics.K, mount.intrinsics.K)
            assert np.abs(view.T_flange_camera - mount.T_flange_camera).max() < 1e-12
            # base -> tool0 is the forward kinematics of the recorded actual joints
            fk = model.flange_pose(view.joint_positions)
            assert np.abs(fk - view.T_base_flange).max() < 1e-9
            depth = view.depth
            assert depth.shape == view.image.shape[:2] and np.isfinite(depth).mean() > 0.5
