"""MockArm: trapezoidal timing, straight linear moves through IK, noise, faults, validation."""

from __future__ import annotations

import time

import numpy as np
import pytest

from armstereo.clock import RealClock, SimClock
from armstereo.devices import MAX_JOINT_SPEED, MAX_LINEAR_SPEED, ArmState
from armstereo.errors import (
    ConfigError,
    ConnectionLost,
    IKError,
    JointLimitError,
    MotionTimeout,
    NotConnected,
    ProtectiveStop,
)
from armstereo.kinematics import ArmModel, ready_configuration
from armstereo.transforms import invert, matrix_to_rotvec
from drivers.mock.arm import MockArm, trapezoid_duration, trapezoid_time_at
from drivers.mock.faults import FaultPlan

LIN = dict(speed=0.05, acceleration=0.25)


@pytest.fixture(scope="module")
def model() -> ArmModel:
    return ArmModel.load("ur5e", mount="default_wrist_camera")


class WatchingClock(SimClock):
    """A SimClock that records (time, joints) of the arm before every step of a move."""

    def __init__(self):
        super().__init__(start_ns=0)
        self.arm = None
        self.seen: list[np.ndarray] = []
        self.times: list[float] = []

    def sleep(self, seconds: float) -> None:
        if self.arm is not None and self.arm.is_connected:
            self.seen.append(self.arm.joint_positions())
            self.times.append(self.now())
        super().sleep(seconds)


def make_arm(model, **kw) -> MockArm:
    arm = MockArm(model, **kw)
    arm.connect()
    return arm


def shifted(model, arm, d) -> np.ndarray:
    """Flange target that moves the camera by ``d`` (base frame, m), orientation kept."""
    T_cam = model.camera_pose(arm.joint_positions())
    T_cam[:3, 3] += d
    return T_cam @ invert(model.mount.T_flange_camera)


def test_trapezoid_profile_formulas():
    assert trapezoid_duration(0.1, 0.05, 0.25) == pytest.approx(0.1 / 0.05 + 0.05 / 0.25)
    assert trapezoid_duration(0.004, 0.05, 0.25) == pytest.approx(2 * np.sqrt(0.004 / 0.25))
    assert trapezoid_duration(0.0, 0.05, 0.25) == 0.0
    for d in (0.1, 0.004):
        total = trapezoid_duration(d, 0.05, 0.25)
        s = np.linspace(0, d, 201)
        t = trapezoid_time_at(s, d, 0.05, 0.25)
        assert t[0] == 0 and t[-1] == pytest.approx(total) and np.all(np.diff(t) > 0)
        assert t[100] == pytest.approx(total / 2)  # symmetric profile
        # Speed never exceeds the cap; acceleration phase follows s = a t^2 / 2.
        assert np.max(np.diff(s) / np.diff(t)) <= 0.05 + 1e-9
        assert t[1] == pytest.approx(np.sqrt(2 * s[1] / 0.25))


def test_default_start_is_the_ready_configuration(model):
    arm = make_arm(model)
    np.testing.assert_array_equal(arm.joint_positions(), ready_configuration("ur5e"))
    assert isinstance(arm.clock, SimClock) and arm.status().state is ArmState.NORMAL


def test_linear_move_is_straight_exact_and_takes_the_trapezoid_time(model):
    clock = WatchingClock()
    arm = make_arm(model, clock=clock)
    clock.arm = arm
    T0 = model.flange_pose(arm.joint_positions())
    target = shifted(model, arm, [0.0, 0.1, 0.0])
    arm.move_linear(target, **LIN)
    assert clock.now() == pytest.approx(trapezoid_duration(0.1, **LIN), abs=1e-9)
    T1 = model.flange_pose(arm.joint_positions())
    assert np.linalg.norm(T1[:3, 3] - target[:3, 3]) < 1e-6
    assert np.linalg.norm(matrix_to_rotvec(T1[:3, :3].T @ target[:3, :3])) < 1e-6
    # Every intermediate flange pose lies on the segment with the start orientation.
    seg = target[:3, 3] - T0[:3, 3]
    assert len(clock.seen) > 40
    for q in clock.seen:
        T = model.flange_pose(q)
        off = T[:3, 3] - T0[:3, 3]
        assert np.linalg.norm(np.cross(off, seg)) / np.linalg.norm(seg) < 1e-6
        assert np.allclose(T[:3, :3], T0[:3, :3], atol=1e-6)
    assert arm.history[-1][0] == "move_linear" and arm.moves_started == 1


def test_camera_baseline_is_achieved_to_a_micrometre(model):
    arm = make_arm(model)
    c0 = model.camera_pose(arm.joint_positions())[:3, 3]
    arm.move_linear(shifted(model, arm, [0.0, 0.1, 0.0]), **LIN)
    c1 = model.camera_pose(arm.joint_positions())[:3, 3]
    assert np.linalg.norm(c1 - c0 - [0.0, 0.1, 0.0]) < 1e-6


def test_joint_move_is_synchronised_and_timed(model):
    clock = WatchingClock()
    arm = make_arm(model, clock=clock)
    clock.arm = arm
    q0 = arm.joint_positions()
    delta = np.array([0.2, -0.1, 0.1, 0.0, 0.05, 0.4])
    arm.move_joints(q0 + delta, speed=0.5, acceleration=1.0)
    # The joint with the longest way (0.4 rad) sets the duration; all arrive together.
    assert clock.now() == pytest.approx(trapezoid_duration(0.4, 0.5, 1.0), abs=1e-9)
    np.testing.assert_array_equal(arm.joint_positions(), q0 + delta)
    for q in clock.seen:
        frac = (q - q0)[delta != 0] / delta[delta != 0]
        assert np.ptp(frac) < 1e-12


class SlowJointsModel:
    """The real model with much lower joint velocity limits."""

    def __init__(self, model, limit):
        self._model, self.velocity_limits = model, np.full(6, limit)

    def __getattr__(self, name):
        return getattr(self._model, name)


def test_joint_velocity_limits_are_respected(model):
    clock = WatchingClock()
    arm = make_arm(SlowJointsModel(model, 0.05), clock=clock)
    clock.arm = arm
    q0 = arm.joint_positions()
    arm.move_joints(q0 + [0.0, 0.0, 0.0, 0.0, 0.0, 0.2], speed=0.5, acceleration=1.0)
    assert clock.now() == pytest.approx(trapezoid_duration(0.2, 0.05, 1.0), abs=1e-9)
    clock.seen.clear()
    clock.times.clear()
    t0 = clock.now()
    arm.move_linear(shifted(model, arm, [0.0, 0.1, 0.0]), speed=0.25, acceleration=1.0)
    assert clock.now() - t0 > trapezoid_duration(0.1, 0.25, 1.0) * 1.5  # slowed down
    dq = np.abs(np.diff(np.array(clock.seen), axis=0)).max(axis=1)
    dt = np.diff(clock.times)
    moving = dq > 0
    assert moving.sum() > 40 and np.all(dq[moving] / dt[moving] <= 0.05 * (1 + 1e-6))


def test_realtime_moves_take_real_time(model):
    arm = make_arm(model, realtime=True)
    assert isinstance(arm.clock, RealClock)
    target = shifted(model, arm, [0.0, 0.005, 0.0])
    start = time.perf_counter()
    arm.move_linear(target, **LIN)
    assert time.perf_counter() - start >= trapezoid_duration(0.005, **LIN) - 1e-3


def test_joint_noise_perturbs_the_reached_joints_reproducibly(model):
    q_goal = ready_configuration("ur5e") + 0.05
    reached = []
    for seed in (1, 1, 2):
        arm = make_arm(model, joint_noise=1e-4, seed=seed)
        arm.move_joints(q_goal, speed=0.5, acceleration=1.0)
        reached.append(arm.joint_positions())
        np.testing.assert_array_equal(arm.commanded_q, q_goal)
    assert np.array_equal(reached[0], reached[1]) and not np.array_equal(reached[0], reached[2])
    err = reached[0] - q_goal
    assert np.all(err != 0) and np.max(np.abs(err)) < 1e-3


def test_disconnect_mid_move_stops_part_way_and_keeps_state(model):
    arm = make_arm(model, faults=FaultPlan.parse(["disconnect"]))  # default: the 2nd move
    arm.move_linear(shifted(model, arm, [0.0, 0.05, 0.0]), **LIN)
    p_start = model.flange_pose(arm.joint_positions())[:3, 3]
    target = shifted(model, arm, [0.0, 0.1, 0.0])
    with pytest.raises(ConnectionLost, match="move 2"):
        arm.move_linear(target, **LIN)
    st = arm.status()
    assert st.state is ArmState.DISCONNECTED and not arm.is_connected
    with pytest.raises(ConnectionLost):
        arm.joint_positions()
    with pytest.raises(ConnectionLost):
        arm.move_linear(target, **LIN)
    with pytest.raises(ConnectionLost):
        arm.require_ok()
    arm.stop()  # never raises
    assert [h[0] for h in arm.history] == ["connect", "move_linear", "move_linear",
                                           "move_linear", "stop"]
    arm.connect()  # the link comes back; the arm is where it stopped, half way (in time)
    p = model.flange_pose(arm.joint_positions())[:3, 3]
    way = np.linalg.norm(p - p_start) / np.linalg.norm(target[:3, 3] - p_start)
    assert 0.45 < way < 0.55
    assert arm.status().ok


def test_protective_stop_mid_move(model):
    arm = make_arm(model, faults=FaultPlan.parse(["protective-stop@1"]))
    q_start = arm.joint_positions()
    target = shifted(model, arm, [0.0, 0.1, 0.0])
    with pytest.raises(ProtectiveStop, match="move 1"):
        arm.move_linear(target, **LIN)
    assert arm.status().state is ArmState.PROTECTIVE_STOP
    q_stop = arm.joint_positions()  # still readable
    assert not np.allclose(q_stop, q_start) and not np.allclose(
        model.flange_pose(q_stop), target, atol=1e-3)
    with pytest.raises(ProtectiveStop):
        arm.move_joints(q_start, speed=0.5, acceleration=1.0)
    with pytest.raises(ProtectiveStop):
        arm.require_ok()
    arm.stop()
    arm.recover_protective_stop()
    arm.move_linear(target, **LIN)  # move 3 (the refused one counted as none)
    assert np.linalg.norm(model.flange_pose(arm.joint_positions())[:3, 3] - target[:3, 3]) < 1e-6


def test_stuck_move_and_slow_move_time_out_on_the_callers_timeout(model):
    arm = make_arm(model, faults=FaultPlan.parse(["stuck-move@1"]))
    t0 = arm.clock.now_ns()
    with pytest.raises(MotionTimeout, match="stuck"):
        arm.move_linear(shifted(model, arm, [0.0, 0.1, 0.0]), timeout=5.0, **LIN)
    assert arm.clock.now_ns() - t0 == 5_000_000_000
    assert arm.status().ok
    slow = make_arm(model)
    t0 = slow.clock.now_ns()
    with pytest.raises(MotionTimeout, match="more than the 1 s timeout"):
        slow.move_linear(shifted(model, slow, [0.0, 0.1, 0.0]), timeout=1.0, **LIN)
    assert slow.clock.now_ns() - t0 == 1_000_000_000


class PickyModel:
    """The real model, except that IK fails (or flips branch) in a band across the path."""

    def __init__(self, model, y_band, flip=False):
        self._model, self._band, self._flip = model, y_band, flip

    def __getattr__(self, name):
        return getattr(self._model, name)

    def ik(self, T, q_seed, **kw):
        q = self._model.ik(T, q_seed, **kw)
        if self._band[0] < T[1, 3] < self._band[1]:
            if not self._flip:
                raise IKError("no convergence (test band)", "no_convergence")
            q = q + np.array([0, 0, 0, 0, 0, 0.5])
        return q


def test_paths_failing_ik_part_way_are_refused_before_moving(model):
    arm = make_arm(model)
    q0, t0 = arm.joint_positions(), arm.clock.now_ns()
    with pytest.raises(IKError):
        arm.move_linear(shifted(model, arm, [-2.0, 0.0, 0.0]), **LIN)  # out of reach
    y0 = model.flange_pose(q0)[1, 3]
    target = shifted(model, arm, [0.0, 0.1, 0.0])
    model.ik(target, q0)  # the end itself is reachable
    for flip, words in ((False, "no IK at 5"), (True, "jump")):
        picky = make_arm(PickyModel(model, (y0 + 0.049, y0 + 0.053), flip=flip))
        t_picky = picky.clock.now_ns()
        with pytest.raises(IKError, match=f"before moving.*{words}"):
            picky.move_linear(target, **LIN)
        np.testing.assert_array_equal(picky.joint_positions(), q0)
        assert picky.clock.now_ns() == t_picky and picky.moves_started == 0
    assert arm.clock.now_ns() == t0 and arm.moves_started == 0
    np.testing.assert_array_equal(arm.joint_positions(), q0)


def test_inputs_are_validated(model):
    arm = make_arm(model)
    q = arm.joint_positions()
    T = model.flange_pose(q)
    for bad_q in (q[:5], np.r_[q[:5], np.nan], "abc"):
        with pytest.raises(ConfigError):
            arm.move_joints(bad_q, speed=0.5, acceleration=1.0)
    for speed in (0.0, -0.1, MAX_JOINT_SPEED * 1.01, float("nan")):
        with pytest.raises(ConfigError):
            arm.move_joints(q, speed=speed, acceleration=1.0)
    with pytest.raises(ConfigError):
        arm.move_linear(T, speed=MAX_LINEAR_SPEED * 1.01, acceleration=0.25)
    with pytest.raises(ConfigError):
        arm.move_linear(T, speed=0.05, acceleration=0.0)
    with pytest.raises(ConfigError):
        arm.move_linear(T, speed=0.05, acceleration=0.25, timeout=0)
    skewed = T.copy()
    skewed[:3, :3] *= 1.1
    with pytest.raises(ConfigError):
        arm.move_linear(skewed, **LIN)
    with pytest.raises(JointLimitError):
        arm.move_joints(model.upper + 0.1, speed=0.5, acceleration=1.0)
    assert arm.moves_started == 0
    with pytest.raises(NotConnected, match="already connected"):
        arm.connect()
    arm.close()
    arm.close()
    with pytest.raises(NotConnected, match="not connected"):
        arm.joint_positions()
    with pytest.raises(ConfigError):
        MockArm(model, clock=SimClock(), realtime=True)
    with pytest.raises(ConfigError):
        MockArm(model, joint_noise=-1.0)
    with pytest.raises(ConfigError):
        MockArm(model, q0=[0.0, 1.0])
