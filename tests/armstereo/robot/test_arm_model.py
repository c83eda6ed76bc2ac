"""ArmModel: FK against an independent DH computation, Jacobian, limits, IK, camera poses."""

import hashlib
import logging

import numpy as np
import pytest

from armstereo.errors import ConfigError, IKError, JointLimitError
from armstereo.mount import CameraMount
from armstereo.robot.arm_model import (
    JOINT_NAMES,
    MODEL_NAMES,
    ArmModel,
    ready_configuration,
)
from armstereo.transforms import invert, make_T, rot_x, rot_z
from robot_models import MODELS_DIR

log = logging.getLogger(__name__)

# UR's published standard DH lengths (m): d1, a2, a3, d4, d5, d6 (docs/ur-robots.md §2),
# typed in again here so the test does not share a table with the URDF generator.
DH = {
    "ur3e": (0.15185, -0.24355, -0.2132, 0.13105, 0.08535, 0.0921),
    "ur5e": (0.1625, -0.425, -0.3922, 0.1333, 0.0997, 0.0996),
    "ur10e": (0.1807, -0.6127, -0.57155, 0.17415, 0.11985, 0.11655),
    "ur16e": (0.1807, -0.4784, -0.36, 0.17415, 0.11985, 0.11655),
    "ur5": (0.089159, -0.425, -0.39225, 0.10915, 0.09465, 0.0823),
}
ALPHA = (np.pi / 2, 0, 0, np.pi / 2, -np.pi / 2, 0)
POS_TOL = 1e-9  # m


def dh_fk(name, q):
    """T_base_tool0 by the textbook product Rz(q) Tz(d) Tx(a) Rx(alpha), numpy only."""
    d1, a2, a3, d4, d5, d6 = DH[name]
    a, d = (0, a2, a3, 0, 0, 0), (d1, 0, 0, d4, d5, d6)
    T = np.eye(4)
    for qi, ai, di, al in zip(q, a, d, ALPHA, strict=True):
        ct, st, ca, sa = np.cos(qi), np.sin(qi), np.cos(al), np.sin(al)
        T = T @ np.array([[ct, -st * ca, st * sa, ai * ct],
                          [st, ct * ca, -ct * sa, ai * st],
                          [0, sa, ca, di],
                          [0, 0, 0, 1]])
    return T


@pytest.fixture(scope="module")
def arms():
    return {n: ArmModel.load(n, mount="default_wrist_camera") for n in MODEL_NAMES}


@pytest.fixture(scope="module")
def ur5e(arms):
    return arms["ur5e"]


def pose_error(T_a, T_b):
    """(position error m, rotation error rad) between two poses."""
    # ||R_a - R_b||_F = 2 sqrt(2) sin(angle / 2): accurate for tiny angles, unlike arccos.
    chord = np.linalg.norm(T_a[:3, :3] - T_b[:3, :3]) / (2 * np.sqrt(2))
    angle = 2 * np.arcsin(min(chord, 1.0))
    return float(np.linalg.norm(T_a[:3, 3] - T_b[:3, 3])), float(angle)


# ---- loading -----------------------------------------------------------------------------
def test_load_by_name_case_insensitive_and_by_path(ur5e):
    arm = ArmModel.load("UR5e")
    assert arm.name == "ur5e" and arm.mount is None
    assert arm.urdf_path == MODELS_DIR / "ur5e.urdf"
    assert arm.urdf_sha256 == hashlib.sha256(arm.urdf_path.read_bytes()).hexdigest()
    by_path = ArmModel.load(MODELS_DIR / "ur5e.urdf", mount=ur5e.mount)
    assert by_path.name == "ur5e" and by_path.mount is ur5e.mount
    assert arm.joint_names == JOINT_NAMES
    assert np.allclose(arm.velocity_limits, np.pi)
    assert arm.upper[2] == pytest.approx(np.pi) and arm.lower[0] == pytest.approx(-2 * np.pi)
    with pytest.raises(ValueError):
        arm.lower[0] = 0.0  # the limits are read-only


def test_unknown_model_lists_known_names():
    with pytest.raises(ConfigError, match="ur3e, ur5e, ur10e, ur16e, ur5") as info:
        ArmModel.load("ur7")
    assert "'ur7'" in str(info.value) and "\n" not in str(info.value)


def test_bad_urdf_files_are_config_errors(tmp_path):
    broken = tmp_path / "broken.urdf"
    broken.write_text("<robot name='x'><link name='a'>")
    with pytest.raises(ConfigError, match="broken.urdf"):
        ArmModel.load(broken)
    no_tool = tmp_path / "no_tool.urdf"
    no_tool.write_text((MODELS_DIR / "ur5.urdf").read_text().replace('"tool0"', '"tcp"'))
    with pytest.raises(ConfigError, match="missing frames: \\['tool0'\\]"):
        ArmModel.load(no_tool)


def test_mount_argument_forms(ur5e):
    mount = CameraMount.load("default_wrist_camera")
    assert ArmModel.load("ur5e", mount=mount).mount is mount
    assert ArmModel.load("ur5e", mount="default_wrist_camera").mount.name == mount.name
    with pytest.raises(ConfigError, match="no mount file"):
        ArmModel.load("ur5e", mount="no_such_mount")


# ---- forward kinematics ------------------------------------------------------------------
@pytest.mark.parametrize("name", MODEL_NAMES)
def test_flange_pose_equals_dh_forward_kinematics(arms, name):
    arm = arms[name]
    rng = np.random.default_rng(MODEL_NAMES.index(name))
    worst = 0.0
    for q in rng.uniform(arm.lower, arm.upper, size=(250, 6)):
        worst = max(worst, float(np.abs(arm.flange_pose(q) - dh_fk(name, q)).max()))
    assert worst < POS_TOL


def test_flange_pose_is_in_base_not_base_link(ur5e):
    import pinocchio as pin

    model = pin.buildModelFromUrdf(str(ur5e.urdf_path))
    data = model.createData()
    q = np.array([0.3, -1.1, 1.2, -0.4, 0.9, -2.0])
    pin.framesForwardKinematics(model, data, q)
    T_base_link_tool0 = data.oMf[model.getFrameId("tool0")].homogeneous
    expected = np.diag([-1.0, -1.0, 1.0, 1.0]) @ T_base_link_tool0
    assert np.allclose(ur5e.flange_pose(q), expected, atol=1e-12)
    assert not np.allclose(ur5e.flange_pose(q), T_base_link_tool0, atol=1e-3)


def test_ur5_zero_pose_matches_the_closed_form(arms):
    d1, a2, a3, d4, d5, d6 = DH["ur5"]
    T = arms["ur5"].flange_pose(np.zeros(6))
    assert np.allclose(T[:3, 3], [a2 + a3, -(d4 + d6), d1 - d5], atol=1e-12)
    assert np.allclose(T[:3, 3], [-0.81725, -0.19145, -0.005491], atol=1e-12)


def test_camera_pose_composes_the_mount(ur5e):
    q = np.array([0.1, -1.3, 1.5, -1.7, -1.5, 0.4])
    T_fc = ur5e.mount.T_flange_camera
    T_bc = ur5e.camera_pose(q)
    assert np.allclose(T_bc, ur5e.flange_pose(q) @ T_fc, atol=1e-15)
    assert np.allclose(ur5e.flange_pose_for_camera(T_bc), ur5e.flange_pose(q), atol=1e-12)


def test_camera_pose_without_mount_is_a_config_error():
    arm = ArmModel.load("ur5")
    with pytest.raises(ConfigError, match="no camera mount"):
        arm.camera_pose(np.zeros(6))
    with pytest.raises(ConfigError, match="no camera mount"):
        arm.flange_pose_for_camera(np.eye(4))


@pytest.mark.parametrize("bad", [np.zeros(5), np.zeros((6, 1)), [0, 0, np.nan, 0, 0, 0],
                                 [0, 0, 0, np.inf, 0, 0]])
def test_malformed_joint_vectors_are_config_errors(ur5e, bad):
    for call in (ur5e.flange_pose, ur5e.jacobian, ur5e.check_limits, ur5e.within_limits):
        with pytest.raises(ConfigError, match="q "):
            call(bad)


# ---- Jacobian and singularities ----------------------------------------------------------
def test_jacobian_matches_finite_differences_in_base_frame(ur5e):
    rng = np.random.default_rng(3)
    h = 1e-6
    for q in rng.uniform(-3, 3, size=(20, 6)):
        J, T = ur5e.jacobian(q), ur5e.flange_pose(q)
        for j in range(6):
            dq = np.zeros(6)
            dq[j] = h
            Tp, Tm = ur5e.flange_pose(q + dq), ur5e.flange_pose(q - dq)
            v = (Tp[:3, 3] - Tm[:3, 3]) / (2 * h)
            W = (Tp[:3, :3] - Tm[:3, :3]) / (2 * h) @ T[:3, :3].T  # skew(omega), base axes
            w = np.array([W[2, 1], W[0, 2], W[1, 0]])
            assert np.allclose(J[:3, j], v, atol=1e-7)
            assert np.allclose(J[3:, j], w, atol=1e-7)


def test_sigma_min_collapses_at_wrist_singularity_and_not_at_ready(arms):
    for name, arm in arms.items():
        q = np.array([0.3, -1.2, 1.4, -0.8, 0.0, 0.5])  # wrist 2 at 0: wrist 1 and 3 align
        assert arm.sigma_min(q) < 1e-9, name
        assert arm.sigma_min(ready_configuration(name)) > 0.1, name


# ---- limits ------------------------------------------------------------------------------
def test_check_limits_message_names_joint_value_limit_and_margin(ur5e):
    q = np.array([0.0, -1.0, 1.0, 0.0, 6.40, 0.0])
    with pytest.raises(JointLimitError) as info:
        ur5e.check_limits(q, margin=0.1)
    assert str(info.value) == "wrist_2_joint = 6.40 rad is outside [-6.28, 6.28] - margin 0.10"
    assert not ur5e.within_limits(q, 0.1)
    q[4] = 6.2
    ur5e.check_limits(q)
    assert ur5e.within_limits(q) and not ur5e.within_limits(q, margin=0.1)
    with pytest.raises(JointLimitError, match=r"^elbow_joint = -3.20 rad is outside "
                                              r"\[-3.14, 3.14\]$"):
        ur5e.check_limits([0, 0, -3.2, 0, 0, 0])
    with pytest.raises(ConfigError, match="margin"):
        ur5e.within_limits(np.zeros(6), margin=-0.1)


# ---- ready configuration -----------------------------------------------------------------
def test_ready_configuration_points_the_flange_down_in_front(arms):
    for name, arm in arms.items():
        T = arm.flange_pose(ready_configuration(name))
        assert np.allclose(T[:3, 2], [0, 0, -1], atol=1e-12), name
        assert T[0, 3] < -0.25 and T[2, 3] > 0.25, name
        arm.check_limits(ready_configuration(name), margin=0.5)
    T = arms["ur5e"].flange_pose(ready_configuration("UR5e"))
    assert np.allclose(T[:3, 3], [-0.4919, -0.1333, 0.4879], atol=1e-3)
    with pytest.raises(ConfigError, match="ur5e"):
        ready_configuration("ur7")
    q = ready_configuration("ur5")
    q[0] = 1.0
    assert ready_configuration("ur5")[0] == 0.0


# ---- inverse kinematics ------------------------------------------------------------------
def solve_round_trips(arm, qs, rng, seed_sigma):
    """IK from perturbed seeds to FK(q); returns (solved flags, max position/angle error)."""
    ok, worst = [], (0.0, 0.0)
    for q in qs:
        T = arm.flange_pose(q)
        try:
            sol = arm.ik(T, q + rng.normal(0, seed_sigma, 6))
        except IKError:
            ok.append(False)
            continue
        ok.append(True)
        err = pose_error(arm.flange_pose(sol), T)
        worst = (max(worst[0], err[0]), max(worst[1], err[1]))
        assert arm.within_limits(sol)
    return np.array(ok), worst


def well_conditioned(arm, rng, n, sigma=0.05):
    """Random joint vectors inside the limits (0.3 rad margin) with sigma_min >= sigma."""
    out = []
    while len(out) < n:
        q = rng.uniform(arm.lower + 0.3, arm.upper - 0.3)
        if arm.sigma_min(q) >= sigma:
            out.append(q)
    return np.array(out)


@pytest.mark.parametrize("name", MODEL_NAMES)
def test_ik_round_trips_on_well_conditioned_targets(arms, name):
    arm, rng = arms[name], np.random.default_rng(11)
    ok, (pos, ang) = solve_round_trips(arm, well_conditioned(arm, rng, 60), rng, 0.05)
    assert ok.all()
    assert pos < 1e-9 and ang < 1e-9


def test_ik_success_rate_on_unfiltered_random_targets(ur5e):
    # Unfiltered q in +-2.5 rad includes near-singular targets; 200/200 solve with this seed.
    rng = np.random.default_rng(5)
    ok, (pos, _) = solve_round_trips(ur5e, rng.uniform(-2.5, 2.5, size=(200, 6)), rng, 0.05)
    log.info("IK success on unfiltered random targets: %d/%d", ok.sum(), ok.size)
    assert ok.mean() >= 0.98 and pos < 1e-9


def test_ik_stays_on_the_seed_branch_for_baseline_moves(ur5e):
    q0 = ready_configuration("ur5e")
    T_cam = ur5e.camera_pose(q0)
    for axis in range(3):
        for step in (-0.1, 0.1):
            T = T_cam @ make_T(np.eye(3), np.eye(3)[axis] * step)
            q = ur5e.ik(ur5e.flange_pose_for_camera(T), q0, margin=0.1)
            assert pose_error(ur5e.camera_pose(q), T)[0] < 1e-9
            assert np.abs(q - q0).max() < 0.6  # same elbow/wrist branch, no extra turn


def test_ik_result_is_the_turn_nearest_the_seed(ur5e):
    q = np.array([0.2, -1.4, 1.3, -1.5, -1.6, 5.9])
    sol = ur5e.ik(ur5e.flange_pose(q), q + 0.02)
    assert np.allclose(sol, q, atol=1e-7)
    seed = q.copy()
    seed[5] -= 2 * np.pi  # same pose one wrist turn lower: the answer follows the seed
    sol = ur5e.ik(ur5e.flange_pose(q), seed)
    assert sol[5] == pytest.approx(q[5] - 2 * np.pi, abs=1e-7)


def test_ik_refuses_far_targets(ur5e):
    q0 = ready_configuration("ur5e")
    T = ur5e.flange_pose(q0)
    T[:3, 3] = [3.0, 0.0, 0.0]
    with pytest.raises(IKError, match="3.00 m .* reach") as info:
        ur5e.ik(T, q0)
    assert info.value.reason == "unreachable"
    T[:3, 3] = [-0.95, -0.13, 0.2]  # inside the crude reach bound, outside the workspace
    with pytest.raises(IKError) as info:
        ur5e.ik(T, q0)
    assert info.value.reason in ("singular", "no_convergence")
    assert " mm " in str(info.value) and "\n" not in str(info.value)


def test_ik_no_convergence_reports_the_remaining_error(ur5e):
    q0 = ready_configuration("ur5e")
    T = ur5e.flange_pose(q0) @ make_T(rot_x(0.5), [0.1, 0.05, 0.0])
    with pytest.raises(IKError, match=r"did not converge: [\d.]+ mm / [\d.]+ deg left after 2 "
                                      r"iterations") as info:
        ur5e.ik(T, q0, max_iter=2)
    assert info.value.reason == "no_convergence"


def test_ik_rejects_solutions_outside_limits_with_margin(ur5e):
    q = np.array([0.2, -1.4, 1.3, -1.5, -1.6, 6.2])  # wrist 3 inside the limit, not the margin
    T = ur5e.flange_pose(q)
    assert np.allclose(ur5e.ik(T, q), q, atol=1e-7)
    with pytest.raises(IKError, match="wrist_3_joint = 6.20 rad is outside .* margin 0.10") as e:
        ur5e.ik(T, q, margin=0.1)
    assert e.value.reason == "joint_limits"
    q = np.array([0.2, -0.4, 3.1, -1.5, -1.6, 0.0])  # elbow folded to 3.1 of +-pi
    with pytest.raises(IKError, match="elbow_joint") as e:
        ur5e.ik(ur5e.flange_pose(q), q, margin=0.1)
    assert e.value.reason == "joint_limits"


def test_ik_rejects_malformed_targets(ur5e):
    q0 = ready_configuration("ur5e")
    with pytest.raises(ConfigError, match="4x4"):
        ur5e.ik(np.eye(3), q0)
    skewed = np.eye(4)
    skewed[0, 1] = 0.1
    with pytest.raises(ConfigError, match="rigid"):
        ur5e.ik(skewed, q0)
    with pytest.raises(ConfigError, match="q_seed"):
        ur5e.ik(np.eye(4), q0[:5])


def test_ik_accepts_a_slightly_unnormalised_rotation(ur5e):
    q = np.array([0.1, -1.3, 1.5, -1.7, -1.5, 0.4])
    T = ur5e.flange_pose(q) @ make_T(rot_z(0.05), [0.01, 0, 0])
    T_noisy = T.copy()
    T_noisy[:3, :3] *= 1 + 1e-8  # e.g. a pose that went through float32
    sol = ur5e.ik(T_noisy, q)
    pos, ang = pose_error(ur5e.flange_pose(sol), T)
    assert pos < 1e-9 and ang < 1e-7
    assert np.allclose(invert(T) @ ur5e.flange_pose(sol), np.eye(4), atol=1e-7)


def test_custom_urdf_needs_base_fixed_to_the_root(tmp_path):
    # Hang the chain from base_link and 'base' from the last link: base now moves with q.
    text = (MODELS_DIR / "ur5.urdf").read_text()
    text = text.replace('<parent link="base"/>', '<parent link="base_link"/>')
    text = text.replace('<parent link="base_link"/>\n    <child link="base"/>',
                        '<parent link="wrist_3_link"/>\n    <child link="base"/>')
    moved = tmp_path / "moved_base.urdf"
    moved.write_text(text)
    with pytest.raises(ConfigError, match="must be fixed to the root"):
        ArmModel.load(moved)


def test_the_old_module_path_hands_on_the_same_model():
    import armstereo.kinematics as old
    import armstereo.robot.arm_model as new

    assert old.ArmModel is new.ArmModel and old.ready_configuration is new.ready_configuration
    assert all(getattr(old, name) is getattr(new, name) for name in old.__all__)
