"""DH tables, FK by 4x4 composition, hashes and FK differences (armstereo.robot.dh)."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from armstereo.errors import ConfigError
from armstereo.robot.arm_model import MODEL_NAMES, ArmModel
from armstereo.robot.dh import (
    NOMINAL_MODELS,
    DHTable,
    fk,
    fk_difference,
    frames,
    identify_model,
    nominal_table,
    pose_difference,
    ur_calibration_hash,
    workspace_joints,
)
from armstereo.robot.synthetic import synthetic_calibration
from armstereo.transforms import rot_x, rot_z
from robot_models.generate_urdfs import SPECS

# The table URSim 5.8 broadcasts for a UR5e (UR's client library tests; tests/data/ur_primary).
URSIM_UR5E = DHTable("ur5e", theta=(0,) * 6, a=(0, -0.425, -0.3922, 0, 0, 0),
                     d=(0.1625, 0, 0, 0.1333, 0.0997, 0.0996),
                     alpha=(1.570796327, 0, 0, 1.570796327, -1.570796327, 0))
URSIM_UR5E_UR_HASH = "calib_12788084448423163542"  # published by UR for URSim's UR5e


def random_joints(n: int, seed: int = 1) -> np.ndarray:
    return np.random.default_rng(seed).uniform(-2 * np.pi, 2 * np.pi, size=(n, 6))


def test_nominal_tables_are_the_numbers_the_urdfs_are_generated_from():
    assert set(NOMINAL_MODELS) == set(MODEL_NAMES)
    for spec in SPECS:
        table = nominal_table(spec.name.upper())
        assert table.model == spec.name and table.is_nominal
        assert table.theta == (0.0,) * 6
        assert table.d == (spec.d1, 0.0, 0.0, spec.d4, spec.d5, spec.d6)
        assert table.a == (0.0, spec.a2, spec.a3, 0.0, 0.0, 0.0)
        assert table.alpha == (math.pi / 2, 0.0, 0.0, math.pi / 2, -math.pi / 2, 0.0)
        assert table.calibration_status is None and table.checksums is None
    with pytest.raises(ConfigError, match="ur20"):
        nominal_table("ur20")


@pytest.mark.parametrize("name", MODEL_NAMES)
def test_nominal_fk_equals_the_urdf_model(name):
    arm, table = ArmModel.load(name), nominal_table(name)
    for q in random_joints(50):
        np.testing.assert_allclose(fk(table, q), arm.flange_pose(q), atol=1e-12)


def test_fk_at_zero_by_hand():
    # q = 0: all rotations are about x (alpha1 + alpha4 + alpha5 = pi/2), the flange sits at
    # (a2 + a3, -(d4 + d6), d1 - d5).
    t = nominal_table("ur5e")
    T = fk(t, np.zeros(6))
    np.testing.assert_allclose(T[:3, 3], [-0.425 - 0.3922, -(0.1333 + 0.0996), 0.1625 - 0.0997],
                               atol=1e-15)
    np.testing.assert_allclose(T[:3, :3], rot_x(math.pi / 2), atol=1e-15)


def test_theta_is_a_joint_offset():
    base = nominal_table("ur5e")
    offset = np.array([0.1, -0.2, 0.3, -0.4, 0.5, -0.6])
    shifted = dataclasses.replace(base, theta=tuple(offset))
    for q in random_joints(10):
        np.testing.assert_allclose(fk(shifted, q), fk(base, q + offset), atol=1e-13)


def test_batched_fk_and_frames_agree_with_single():
    t = synthetic_calibration("ur10e", 3)
    q = random_joints(20)
    batch, F = fk(t, q), frames(t, q)
    assert batch.shape == (20, 4, 4) and F.shape == (20, 7, 4, 4)
    for i in range(20):
        np.testing.assert_array_equal(batch[i], fk(t, q[i]))
        np.testing.assert_allclose(F[i, 6], batch[i], atol=1e-12)
        np.testing.assert_array_equal(F[i, 0], np.eye(4))


def test_fk_refuses_bad_joints():
    t = nominal_table("ur5e")
    with pytest.raises(ConfigError, match="shape"):
        fk(t, np.zeros(5))
    with pytest.raises(ConfigError, match="finite"):
        fk(t, [0, 0, np.nan, 0, 0, 0])


def test_table_validation():
    good = nominal_table("ur5e")
    with pytest.raises(ConfigError, match="6 finite"):
        dataclasses.replace(good, a=(0.0,) * 5)
    with pytest.raises(ConfigError, match="6 finite"):
        dataclasses.replace(good, alpha=(math.nan,) * 6)
    with pytest.raises(ConfigError, match="length beyond"):
        dataclasses.replace(good, d=(2e4, 0, 0, 0, 0, 0))
    with pytest.raises(ConfigError, match="uint32"):
        dataclasses.replace(good, checksums=(2**32,) * 6)
    # Real calibrated tables carry d of hundreds of metres: those are fine.
    dataclasses.replace(good, d=(0.16, 300.0, -310.0, 10.0, 0.1, 0.1))


def test_sha256_is_exact_and_ignores_metadata():
    t = nominal_table("ur5e")
    assert t.sha256 == nominal_table("ur5e").sha256
    # Pinned: the hash is what recordings and model files store, so it must never drift.
    assert t.sha256 == "8cf1f27baa85ff85b88d325094bcd056ae75df67ef3a3365b3dc76c93ad58f85"
    one_ulp = dataclasses.replace(t, d=(np.nextafter(0.1625, 1.0),) + t.d[1:])
    assert one_ulp.sha256 != t.sha256
    assert dataclasses.replace(t, theta=(-0.0,) * 6).sha256 == t.sha256
    stamped = dataclasses.replace(t, source="controller", calibration_status=2,
                                  checksums=(1, 2, 3, 4, 5, 6), model="")
    assert stamped.sha256 == t.sha256


def test_ur_calibration_hash_matches_the_published_ursim_value():
    assert ur_calibration_hash(URSIM_UR5E) == URSIM_UR5E_UR_HASH
    # It reads 6 significant digits only: pi/2 and URSim's 1.570796327 print alike.
    assert ur_calibration_hash(nominal_table("ur5e")) == URSIM_UR5E_UR_HASH
    assert ur_calibration_hash(synthetic_calibration("ur5e", 1)) != URSIM_UR5E_UR_HASH


def test_fk_difference_known_cases():
    t = nominal_table("ur5e")
    q = random_joints(30)
    assert fk_difference(t, t, q) == (0.0, 0.0)
    taller = dataclasses.replace(t, d=(t.d[0] + 0.001,) + t.d[1:])
    diff = fk_difference(t, taller, q)
    assert diff.translation_mm == pytest.approx(1.0, abs=1e-9)
    assert diff.rotation_deg == pytest.approx(0.0, abs=1e-9)
    # A turn of the last joint's zero spins the flange about its own z, in place.
    spun = dataclasses.replace(t, theta=(0, 0, 0, 0, 0, 0.01))
    diff = fk_difference(t, spun, q)
    assert diff.translation_mm == pytest.approx(0.0, abs=1e-9)
    assert diff.rotation_deg == pytest.approx(math.degrees(0.01), rel=1e-9)


def test_pose_difference_is_exact_for_tiny_angles():
    T = np.eye(4)
    for angle in (1e-10, 1e-6, 0.3, 3.0):
        R = np.eye(4)
        R[:3, :3] = rot_z(angle) @ rot_x(0.0)
        lin, ang = pose_difference(T, R)
        assert lin == 0.0
        assert ang == pytest.approx(angle, rel=1e-9)


def test_identify_model():
    for name in NOMINAL_MODELS:
        found, diff = identify_model(nominal_table(name))
        assert found == name and diff == (0.0, 0.0)
        found, diff = identify_model(synthetic_calibration(name, 5))
        assert found == name and 0.1 < diff.translation_mm < 20.0


def test_workspace_joints_are_reproducible():
    np.testing.assert_array_equal(workspace_joints(10), workspace_joints(10))
    q = workspace_joints()
    assert q.shape == (1000, 6) and np.abs(q).max() <= np.pi
