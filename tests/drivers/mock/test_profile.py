"""The mock's error profiles: a realistic mock errs like real hardware, the ideal one not at all."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from armstereo import backends
from armstereo.errors import ConfigError
from armstereo.kinematics import ArmModel
from armstereo.mount import CameraMount
from armstereo.robot.dh import fk_difference, nominal_table, pose_difference, workspace_joints
from armstereo.robot.synthetic import synthetic_calibration
from drivers.mock.arm import STEADY_RAD, MockArm
from drivers.mock.broadcast import read_broadcast, robot_state, version_message
from drivers.mock.camera import MockCamera, true_intrinsics, true_mount
from drivers.mock.imaging import apply_effects, vignetting_map
from drivers.mock.profile import (
    IDEAL,
    REALISTIC,
    ImageEffects,
    get_profile,
    offset_transform,
    parse_offset,
)
from drivers.ur.primary_format import MessageSplitter, parse_robot_state


@pytest.fixture(scope="module")
def model() -> ArmModel:
    return ArmModel.load("ur5e", mount=CameraMount.load(None))


def connected(model, profile="realistic", seed=0):
    arm = backends.build_arm("mock", backends.arm_config("mock", profile=profile, seed=seed),
                             model)
    arm.connect()
    return arm


def test_realistic_arm_is_a_factory_calibrated_arm_and_broadcasts_its_table(model):
    arm = connected(model, seed=4)
    truth = synthetic_calibration("ur5e", 4)
    kin = arm.kinematics
    assert kin.calibrated and kin.warnings == ()
    assert kin.table.sha256 == truth.sha256 and kin.table.calibration_status == 2
    # millimetres from nominal, like a real arm
    assert 1.0 < kin.nominal_difference.translation_mm < 15.0
    # the arm moves and reports with those true kinematics
    q, T = arm.joints_and_controller_pose()
    assert np.allclose(T, ArmModel.from_dh(truth).flange_pose(q), atol=1e-12)
    assert pose_difference(T, model.flange_pose(q))[0] > 1e-4


def test_ideal_arm_is_the_software_model_and_broadcasts_nothing(model):
    arm = connected(model, profile="ideal")
    assert arm.kinematics is None and arm.model is model
    q1, q2 = arm.joint_positions(), arm.joint_positions()
    assert np.array_equal(q1, q2)  # no encoder noise
    assert np.array_equal(arm.true_flange_pose(), model.flange_pose(q1))


def test_broadcast_bytes_are_what_the_ur_decoder_reads():
    table = synthetic_calibration("ur5e", 2)
    q = np.array([0.1, -1.2, 1.3, -1.6, -1.57, 0.2])
    T = ArmModel.from_dh(table).flange_pose(q)
    messages = MessageSplitter().feed(version_message() + robot_state(table, q, T))
    assert [kind for kind, _ in messages] == [20, 16]
    state = parse_robot_state(messages[1][1])
    assert state.valid and np.array_equal(state.joints, q)
    assert state.kinematics.theta == table.theta and state.kinematics.d == table.d
    kin = read_broadcast(table, q, T, expected_model="ur5e")
    assert kin.calibrated and kin.table.sha256 == table.sha256
    with pytest.raises(ConfigError, match="really a ur10e"):  # the wrong model is refused
        read_broadcast(table, q, T, expected_model="ur10e")


def test_encoder_noise_and_ringing_after_a_move(model):
    arm = connected(model, seed=1)
    T = arm.model.flange_pose(arm.joint_positions())
    T[:3, 3] += [0.0, 0.03, 0.0]
    arm.move_linear(T, 0.05, 0.25)
    q_true_at_stop = arm._true_q()
    readings = np.array([arm.joint_positions() for _ in range(200)])
    noise = REALISTIC.joints.encoder_noise_rad
    # encoder noise: zero-mean, of the profile's size, around the (ringing) true joints
    assert 0.7 * noise < np.std(readings - arm._true_q(), axis=0).mean() < 1.3 * noise
    t_stop = arm.clock.now()
    arm.wait_until_steady()
    waited = arm.clock.now() - t_stop
    ring = REALISTIC.joints
    assert waited == pytest.approx(ring.settle_time_constant_s
                                   * np.log(ring.settle_amplitude_rad / STEADY_RAD), abs=1e-6)
    assert np.max(np.abs(arm._true_q() - arm._q)) <= STEADY_RAD
    arm.clock.sleep(0.5)  # the settle time: the ringing has decayed to nothing
    assert np.max(np.abs(arm._true_q() - arm._q)) < 1e-6
    assert np.max(np.abs(q_true_at_stop - arm._q)) <= ring.settle_amplitude_rad


def test_realistic_camera_differs_from_its_mount_and_reports_the_mount(model):
    mount = model.mount
    truth = true_mount(mount, REALISTIC, seed=3)
    K, K0 = truth.intrinsics.K, mount.intrinsics.K
    # the bundled mount is a datasheet's and a CAD drawing's: percent, pixels, millimetres and
    # about a degree off, and it knows no distortion
    assert 0.002 < abs(K[0, 0] / K0[0, 0] - 1) < 0.08 and 0 < abs(K[0, 2] - K0[0, 2]) < 20
    assert 0.03 < -truth.intrinsics.dist[0] < 0.2
    lin, ang = pose_difference(truth.T_flange_camera, mount.T_flange_camera)
    assert 5e-4 < lin < 15e-3 and np.radians(0.2) < ang < np.radians(3.0)
    arm = connected(model, seed=3)
    cam = backends.build_camera("mock", backends.camera_config("mock", profile="realistic",
                                                               seed=3), model, arm)
    assert cam.intrinsics is mount.intrinsics  # what the software believes
    assert np.array_equal(cam.true_intrinsics.K, K)
    ideal = true_intrinsics(mount.intrinsics, IDEAL.intrinsics, seed=3)
    assert np.array_equal(ideal.K, K0) and not ideal.has_distortion


def test_hand_eye_offset_moves_the_true_camera_exactly(model):
    offset = parse_offset("0.002,-0.001,0.003,0.1,-0.2,0.05")
    arm = connected(model, profile="ideal")
    plain = MockCamera.from_config(backends.camera_config("mock"), model, arm)
    moved = MockCamera.from_config(backends.camera_config(
        "mock", hand_eye_offset="0.002,-0.001,0.003,0.1,-0.2,0.05"), model, arm)
    expected = plain._pose_source() @ offset_transform(offset)
    assert np.allclose(moved._pose_source(), expected, atol=1e-12)
    T = offset_transform(offset)
    assert np.allclose(T[:3, 3], [0.002, -0.001, 0.003])
    assert np.degrees(pose_difference(T, np.eye(4))[1]) == pytest.approx(
        np.linalg.norm([0.1, -0.2, 0.05]), rel=1e-9)
    for bad in ("1,2,3", "a,b,c,d,e,f", "1,2,3,4,5,nan"):
        with pytest.raises(ConfigError, match="dx,dy,dz,rx,ry,rz"):
            backends.camera_config("mock", hand_eye_offset=bad)


def test_image_effects_are_seeded_and_of_the_stated_sizes():
    flat = np.full((120, 160, 3), 128, np.uint8)
    fx = ImageEffects(read_noise=2.0, vignetting=0.25)
    a = apply_effects(flat, fx, np.random.default_rng(1), gains=np.ones(3))
    b = apply_effects(flat, fx, np.random.default_rng(1), gains=np.ones(3))
    assert np.array_equal(a, b)
    shading = vignetting_map(120, 160, 0.25)
    assert shading[0, 0] == pytest.approx(0.75) and shading.max() == pytest.approx(1.0, abs=1e-4)
    residual = a.astype(float) - 128 * shading[..., None]
    assert abs(residual.mean()) < 0.1 and 1.8 < residual.std() < 2.2  # read noise, sigma 2
    gained = apply_effects(flat, ImageEffects(exposure_rel=0.1), np.random.default_rng(0),
                           gains=np.array([1.1, 1.0, 0.9]))
    assert list(gained[0, 0]) == [141, 128, 115]
    assert apply_effects(flat, ImageEffects(), np.random.default_rng(0)) is flat


def test_realistic_frames_are_not_the_ideal_render(model):
    arm = connected(model, seed=0)
    real = backends.build_camera("mock", backends.camera_config(
        "mock", profile="realistic"), model, arm)
    real.connect()
    f1, f2 = real.grab(), real.grab()
    # the same pose, two exposures: noise and a new exposure / white balance each time
    assert np.abs(f1.image.astype(int) - f2.image.astype(int)).mean() > 1.0
    assert np.isfinite(f1.depth).mean() > 0.99
    truth = real.recording_metadata()
    assert '"profile": "realistic"' in truth["mock_camera_truth"]
    assert '"name": "keypad"' in truth["scene_truth"]


def test_profiles_by_name_and_replace():
    assert get_profile("ideal") is IDEAL and get_profile(REALISTIC) is REALISTIC
    with pytest.raises(ConfigError, match="ideal, realistic"):
        get_profile("perfect")
    with pytest.raises(ConfigError, match="unknown scene"):
        get_profile(dataclasses.replace(IDEAL, scene="moon"))
    assert backends.mock_profile_names() == ("ideal", "realistic")
    # one seeded calibration per arm: the FK error has the size of real ones
    q = workspace_joints(200)
    d = fk_difference(synthetic_calibration("ur5e", 0), nominal_table("ur5e"), q)
    assert 1.0 < d.translation_mm < 15.0


def test_mock_arm_rejects_a_profile_name_it_does_not_know(model):
    with pytest.raises(ConfigError, match="unknown mock profile"):
        MockArm(model, profile="perfect")


def ringing_arm(model):
    """A realistic arm just after a 3 cm move, and how long its ringing takes to quieten (s)."""
    arm = connected(model, seed=1)
    T = arm.model.flange_pose(arm.joint_positions())
    T[:3, 3] += [0.0, 0.03, 0.0]
    arm.move_linear(T, 0.05, 0.25)
    ring = REALISTIC.joints
    return arm, ring.settle_time_constant_s * np.log(ring.settle_amplitude_rad / STEADY_RAD)


def test_waiting_for_steady_gives_up_when_the_ringing_outlasts_the_timeout(model):
    from armstereo.errors import MotionTimeout

    arm, quiet_s = ringing_arm(model)
    t0 = arm.clock.now()
    with pytest.raises(MotionTimeout, match="not steady"):
        arm.wait_until_steady(timeout=0.5 * quiet_s)
    assert arm.clock.now() == t0  # it says so at once, without waiting for nothing
    arm.wait_until_steady(timeout=1.01 * quiet_s)
    assert arm.clock.now() - t0 == pytest.approx(quiet_s, abs=1e-6)


def test_a_steady_arm_is_not_waited_for_again(model):
    arm, quiet_s = ringing_arm(model)
    arm.wait_until_steady()
    arm.clock.sleep(0.2)
    t0 = arm.clock.now()
    arm.wait_until_steady()
    assert arm.clock.now() == t0


def test_without_ringing_the_arm_is_steady_when_the_move_returns(model):
    arm = connected(model, profile="ideal")
    T = arm.model.flange_pose(arm.joint_positions())
    T[:3, 3] += [0.0, 0.03, 0.0]
    arm.move_linear(T, 0.05, 0.25)
    t0 = arm.clock.now()
    arm.wait_until_steady(timeout=1e-3)
    assert arm.clock.now() == t0 and np.array_equal(arm._true_q(), arm._q)


def test_a_wait_after_part_of_the_ringing_waits_only_the_rest(model):
    arm, quiet_s = ringing_arm(model)
    arm.clock.sleep(0.25 * quiet_s)
    t0 = arm.clock.now()
    arm.wait_until_steady()
    assert arm.clock.now() - t0 == pytest.approx(0.75 * quiet_s, abs=1e-6)


def test_the_timeout_itself_is_enough_and_an_arm_that_never_moved_is_steady(model):
    import math

    arm, _ = ringing_arm(model)
    ring = REALISTIC.joints
    quiet_s = ring.settle_time_constant_s * math.log(ring.settle_amplitude_rad / STEADY_RAD)
    arm.wait_until_steady(timeout=quiet_s)  # exactly the time it needs: no timeout
    fresh = connected(model, seed=2)
    t0 = fresh.clock.now()
    fresh.wait_until_steady()
    assert fresh.clock.now() == t0


def test_the_ringing_peaks_at_the_profiles_amplitude_on_its_largest_joint(model):
    """A quarter period after the stop, the largest joint is exactly amplitude x envelope."""
    import math

    arm, _ = ringing_arm(model)
    ring = REALISTIC.joints
    t = 0.25 / ring.settle_frequency_hz
    arm.clock.sleep(t)
    deviation = np.max(np.abs(arm._true_q() - arm._q))
    expected = ring.settle_amplitude_rad * math.exp(-t / ring.settle_time_constant_s)
    assert deviation == pytest.approx(expected, rel=1e-6)


def test_the_realistic_camera_reports_the_exposure_and_white_balance_it_shot_with(model):
    arm = connected(model, seed=4)
    cam = backends.build_camera("mock", backends.camera_config("mock", profile="realistic",
                                                               seed=4), model, arm)
    with cam:
        frames = [cam.grab() for _ in range(3)]  # the same pose: only the sensor changes
    reports = [f.settings for f in frames]
    assert all(set(r) == {"exposure", "balance_ratio"} and r["balance_ratio"][1] == 1.0
               for r in reports)
    assert len({r["exposure"] for r in reports}) == 3
    # what it reports is what the images show: green level ratios follow the exposures
    green = [float(f.image[..., 1].mean()) for f in frames]
    for k in (1, 2):
        assert green[k] / green[0] == pytest.approx(
            reports[k]["exposure"] / reports[0]["exposure"], rel=0.002)
    ideal = connected(model, profile="ideal")
    with backends.build_camera("mock", backends.camera_config("mock"), model, ideal) as plain:
        assert plain.grab().settings is None
