"""The Pinocchio model built from a DH table (armstereo.robot.pinocchio_dh) as ArmModel uses it
(ArmModel.from_dh): same FK as the table, same shape as the URDF models, sane placements."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from armstereo.errors import ConfigError
from armstereo.robot.arm_model import MODEL_NAMES, ArmModel, ready_configuration
from armstereo.robot.dh import fk, nominal_table
from armstereo.robot.pinocchio_dh import joint_placements
from armstereo.robot.synthetic import synthetic_calibration
from armstereo.transforms import make_T, rot_x


def random_joints(n: int, seed: int = 2) -> np.ndarray:
    return np.random.default_rng(seed).uniform(-np.pi, np.pi, size=(n, 6))


@pytest.mark.parametrize("seed", range(5))
def test_calibrated_model_fk_is_the_table_fk(seed):
    table = synthetic_calibration("ur5e", seed)
    arm = ArmModel.from_dh(table)
    for q in random_joints(100, seed):
        np.testing.assert_allclose(arm.flange_pose(q), fk(table, q), atol=1e-12)


@pytest.mark.parametrize("name", MODEL_NAMES)
def test_nominal_table_model_equals_the_urdf_model(name):
    from_urdf, from_dh = ArmModel.load(name), ArmModel.from_dh(nominal_table(name))
    assert from_dh.joint_names == from_urdf.joint_names
    np.testing.assert_array_equal(from_dh.lower, from_urdf.lower)
    np.testing.assert_array_equal(from_dh.upper, from_urdf.upper)
    np.testing.assert_allclose(from_dh.velocity_limits, from_urdf.velocity_limits, rtol=1e-15)
    for q in random_joints(20):
        np.testing.assert_allclose(from_dh.flange_pose(q), from_urdf.flange_pose(q), atol=1e-13)
        np.testing.assert_allclose(from_dh.jacobian(q), from_urdf.jacobian(q), atol=1e-12)
    assert from_dh._reach.radius == pytest.approx(from_urdf._reach.radius, rel=1e-12)


def test_joint_frames_stay_near_their_nominal_places():
    # Raw DH puts some of these frames hundreds of metres away; the built model slides them
    # back along their axes, to millimetres from where the nominal model has its joints.
    def origins_at_zero(placements, T_flange):
        T, out = np.eye(4), []
        for P in placements + [T_flange]:
            T = T @ P
            out.append(T[:3, 3])
        return np.array(out)

    nominal = origins_at_zero(*joint_placements(nominal_table("ur10e")))
    far = 0
    for seed in range(6):
        table = synthetic_calibration("ur10e", seed)
        far += max(abs(v) for v in table.d[1:4]) > 1.0
        calibrated = origins_at_zero(*joint_placements(table))
        assert np.linalg.norm(calibrated - nominal, axis=1).max() < 0.01
        arm = ArmModel.from_dh(table)
        assert arm._reach.radius < 1.05 * ArmModel.load("ur10e")._reach.radius
    assert far >= 3


def test_ik_and_camera_pose_on_a_calibrated_model():
    table = synthetic_calibration("ur5e", 11)
    arm = ArmModel.from_dh(table, mount="default_wrist_camera")
    q0 = ready_configuration("ur5e")
    target = arm.flange_pose(q0) @ make_T(rot_x(0.1), [0.05, -0.02, 0.03])
    q = arm.ik(target, q0)
    np.testing.assert_allclose(arm.flange_pose(q), target, atol=1e-8)
    np.testing.assert_allclose(arm.camera_pose(q),
                               fk(table, q) @ arm.mount.T_flange_camera, atol=1e-8)


def test_from_dh_identity_attributes():
    table = synthetic_calibration("ur3e", 2)
    arm = ArmModel.from_dh(table)
    assert arm.name == "ur3e" and arm.dh is table and arm.urdf_path is None
    assert arm.urdf_sha256 == table.sha256
    assert ArmModel.load("ur3e").dh is None
    with pytest.raises(ConfigError, match="joint limits"):
        ArmModel.from_dh(dataclasses.replace(table, model="ur20"))
