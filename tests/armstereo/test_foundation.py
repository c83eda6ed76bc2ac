"""Transforms, intrinsics and mounts: the shared building blocks."""

import numpy as np
import pytest

from armstereo.camera_model import Intrinsics
from armstereo.errors import ConfigError
from armstereo.mount import CameraMount
from armstereo.transforms import (
    T_from_ur_pose,
    invert,
    make_T,
    matrix_from_quaternion_xyzw,
    matrix_to_rotvec,
    quaternion_xyzw,
    rotvec_to_matrix,
    ur_pose_from_T,
)
from tests.support.geometry import random_rotation


def test_rotvec_round_trip_including_near_pi():
    rng = np.random.default_rng(0)
    for _ in range(200):
        R = random_rotation(rng)
        assert np.allclose(rotvec_to_matrix(matrix_to_rotvec(R)), R, atol=1e-9)
    for angle in (np.pi, np.pi - 1e-8, 1e-10):
        axis = rng.normal(size=3)
        rv = axis / np.linalg.norm(axis) * angle
        assert np.allclose(rotvec_to_matrix(matrix_to_rotvec(rotvec_to_matrix(rv))),
                           rotvec_to_matrix(rv), atol=1e-7)


def test_quaternion_round_trip_and_sign():
    rng = np.random.default_rng(1)
    for _ in range(200):
        R = random_rotation(rng)
        q = quaternion_xyzw(R)
        assert q[3] >= 0 and np.isclose(np.linalg.norm(q), 1.0)
        assert np.allclose(matrix_from_quaternion_xyzw(q), R, atol=1e-9)


def test_ur_pose_and_inverse():
    pose = np.array([0.1, -0.4, 0.3, 0.2, -1.1, 2.9])
    T = T_from_ur_pose(pose)
    assert np.allclose(ur_pose_from_T(T), pose)
    assert np.allclose(T @ invert(T), np.eye(4))
    assert np.allclose(make_T(np.eye(3), [1, 2, 3])[:3, 3], [1, 2, 3])


def test_default_mount_loads():
    m = CameraMount.load()
    assert m.intrinsics.size == (640, 480)
    assert m.T_flange_camera.shape == (4, 4)
    assert len(m.sha256) == 64


def test_bad_mount_and_intrinsics_raise_config_errors(tmp_path):
    with pytest.raises(ConfigError, match="no mount file"):
        CameraMount.load(tmp_path / "missing.toml")
    bad = tmp_path / "bad.toml"
    bad.write_text("name = 'x'\n[hand_eye]\ntranslation = [0, 0]\n")
    with pytest.raises(ConfigError, match="bad.toml"):
        CameraMount.load(bad)
    with pytest.raises(ConfigError):
        Intrinsics(640, 480, np.array([[-1, 0, 0], [0, 1, 0], [0, 0, 1]]))
