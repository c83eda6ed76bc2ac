"""Mock arm: a UR arm simulated through the kinematic model, on a simulated or real clock.

Moves follow a synchronised trapezoidal profile (joint moves: all joints start and stop
together; linear moves: the flange position moves on a straight line and its orientation is
slerped, with the trapezoid in path length, IK solved at every path sample with warm starts).
Time advances on ``clock``: a :class:`SimClock` by default, so moves return at once with the
simulated time advanced by their duration; ``realtime=True`` uses the wall clock and really
sleeps. Optional Gaussian joint noise imitates the arm's repeatability; injected faults
(``drivers.mock.faults``) halt a move part way. Joint vectors are radians in UR order; poses are
flange (``tool0``) poses ``T_base_flange`` in the controller's ``base`` frame.
"""

from __future__ import annotations

import logging
import math
from typing import TYPE_CHECKING, NoReturn

import numpy as np

from armstereo.clock import Clock, RealClock, SimClock
from armstereo.devices import (
    MAX_JOINT_ACCELERATION,
    MAX_JOINT_SPEED,
    MAX_LINEAR_ACCELERATION,
    MAX_LINEAR_SPEED,
    Arm,
    ArmState,
    ArmStatus,
    trapezoid_duration,
)
from armstereo.errors import (
    ConfigError,
    ConnectionLost,
    IKError,
    MotionTimeout,
    ProtectiveStop,
)
from armstereo.transforms import as_rigid, make_T, matrix_to_rotvec, rotvec_to_matrix
from armstereo.validate import positive
from drivers.mock.faults import FAULT_FRACTION, Fault, FaultPlan
from drivers.mock.profile import IDEAL, TAG_JOINTS, MockProfile, get_profile, rng_for
from drivers.mock.residual import PoseResidual

if TYPE_CHECKING:
    from armstereo.kinematics import ArmModel
    from drivers.mock.config import MockArmConfig

log = logging.getLogger(__name__)

# Path sampling of a linear move: IK is solved at least every PATH_STEP_M of flange travel and
# every PATH_STEP_RAD of rotation; joint moves are sampled every JOINT_STEP_RAD.
PATH_STEP_M = 0.002
PATH_STEP_RAD = 0.01
JOINT_STEP_RAD = 0.01
# Rotation limits of a linear move (UR's moveL takes a tool speed; rotation needs its own cap).
LINEAR_ROTATION_SPEED = 0.5  # rad/s
LINEAR_ROTATION_ACCELERATION = 1.0  # rad/s^2
# A joint jump larger than this between neighbouring path samples is an IK branch flip.
MAX_SAMPLE_JUMP_RAD = 0.2
# wait_until_steady returns once the ringing after a move is below this (rad, any joint).
STEADY_RAD = 2e-5


def trapezoid_time_at(s: np.ndarray, distance: float, speed: float,
                      acceleration: float) -> np.ndarray:
    """Time (s) at which a trapezoidal move over ``distance`` reaches positions ``s``."""
    s = np.clip(np.asarray(s, dtype=float), 0.0, distance)
    total = trapezoid_duration(distance, speed, acceleration)
    v_peak = min(speed, math.sqrt(distance * acceleration))
    s_acc = v_peak * v_peak / (2.0 * acceleration)
    t_acc = v_peak / acceleration
    accel = np.sqrt(2.0 * s / acceleration)
    cruise = t_acc + (s - s_acc) / v_peak
    decel = total - np.sqrt(np.maximum(2.0 * (distance - s) / acceleration, 0.0))
    return np.where(s <= s_acc, accel, np.where(s <= distance - s_acc, cruise, decel))


class MockArm(Arm):
    """Simulated 6-joint UR arm implementing :class:`armstereo.devices.Arm`.

    ``q0`` defaults to the model's ready configuration. ``joint_noise`` (rad, Gaussian, seeded
    by ``seed``) perturbs the joints reached at the end of each move. ``faults`` injects
    ``disconnect`` / ``protective-stop`` / ``stuck-move`` into the N-th move started
    (``move_joints`` and ``move_linear`` counted together, from 1); the arm halts half way
    (in time) through that move. Every public call is logged in :attr:`history` as
    ``(method, args)``; what the simulation did on its own (faults, halts) goes to
    :attr:`events`.

    ``profile`` (:mod:`drivers.mock.profile`) says how the arm errs. With its ``kinematics``
    on, the arm's TRUE kinematics are a factory calibration seeded by ``seed``: it moves with
    them (:attr:`model` is the true model, ``true_table`` its DH table) and broadcasts them at
    connect (:attr:`kinematics`, read back through the UR primary-stream reader), while
    ``model`` as given is only what the software believes. With its ``joints`` errors on,
    readings carry encoder noise and the joints ring after each move.
    """

    def __init__(self, model: ArmModel, q0: np.ndarray | None = None, *,
                 clock: Clock | None = None, realtime: bool = False, joint_noise: float = 0.0,
                 seed: int = 0, faults: FaultPlan | None = None, name: str = "mock arm",
                 profile: MockProfile | str = IDEAL):
        if realtime and isinstance(clock, SimClock):
            raise ConfigError(f"{name}: realtime=True needs a real clock, not a SimClock")
        if not (math.isfinite(joint_noise) and joint_noise >= 0):
            raise ConfigError(f"{name}: joint_noise must be >= 0 rad, got {joint_noise}")
        self.profile = get_profile(profile)
        self.believed_model = model
        self.model, self.true_table = _true_kinematics(model, self.profile, seed)
        # what the controller's calibration leaves (realistic profile): physical pose only
        self._residual = (PoseResidual(self.profile.residual, seed)
                          if self.profile.residual.any else None)
        self.kinematics = None  # what the arm broadcast at connect (realistic profile)
        self.name = name
        self.clock = clock if clock is not None else (RealClock() if realtime else SimClock())
        self.joint_noise = float(joint_noise)
        self.faults = faults if faults is not None else FaultPlan()
        if q0 is None:
            from armstereo.kinematics import ready_configuration

            q0 = ready_configuration(model.name)
        self._q = _check_q(q0, "q0", name)
        model.check_limits(self._q)
        self._rng = np.random.default_rng(seed)
        self._joint_rng = rng_for(seed, TAG_JOINTS)
        self._ring_start_ns: int | None = None  # when the last move ended (ringing starts)
        self._ring_shape = np.zeros(6)
        self._connected = False
        self._lost = False
        self._state, self._detail = ArmState.DISCONNECTED, "not connected yet"
        self.history: list[tuple[str, dict]] = []
        self.events: list[str] = []
        self.moves_started = 0
        self.commanded_q: np.ndarray | None = None  # target of the last completed move
        self.last_move_duration = 0.0  # simulated seconds the last move ran

    @classmethod
    def from_config(cls, config: MockArmConfig, model: ArmModel) -> MockArm:
        """The registry's constructor (see :mod:`armstereo.backends`)."""
        from drivers.mock.start_poses import start_joints

        q0 = start_joints(model, config.layout) if config.q0 is None else config.q0
        return cls(model, q0, realtime=config.realtime, joint_noise=config.joint_noise,
                   seed=config.seed, faults=config.fault_plan, profile=config.profile)

    # -- connection ------------------------------------------------------------------------

    def connect(self) -> None:
        """Open the simulated link (also after a lost one: the arm kept its joints)."""
        self.history.append(("connect", {}))
        self._require_not_connected()
        self._connected, self._lost = True, False
        if self._state is ArmState.DISCONNECTED:
            self._state, self._detail = ArmState.NORMAL, ""
        if self.true_table is not None and self.kinematics is None:
            from drivers.mock.broadcast import read_broadcast

            q = self._reading()
            self.kinematics = read_broadcast(self.true_table, q, self.model.flange_pose(q),
                                             expected_model=self.believed_model.name,
                                             name=self.name)

    def close(self) -> None:
        self.history.append(("close", {}))
        if self._connected:
            self._connected = False
            self._state, self._detail = ArmState.DISCONNECTED, "closed"

    def status(self) -> ArmStatus:
        return ArmStatus(self._state, self._detail)

    def recover_protective_stop(self, timeout: float = 15.0) -> None:
        """Clear a protective stop (what the teach pendant's 'unlock' does); at once."""
        self.history.append(("recover_protective_stop", {"timeout": timeout}))
        self._require_link()
        if self._state is ArmState.PROTECTIVE_STOP:
            self._state, self._detail = ArmState.NORMAL, ""

    # -- state -----------------------------------------------------------------------------

    def joint_positions(self) -> np.ndarray:
        """Actual joints (6,), radians, as the encoders read them (with the repeatability noise
        of the last move; with the profile's joint errors, also encoder noise and ringing)."""
        self._require_link()
        return self._reading()

    def joints_and_controller_pose(self) -> tuple[np.ndarray, np.ndarray]:
        """One joint reading (rad) and the flange pose ``T_base_flange`` the controller
        computes from it with its own (true) kinematics: what one RTDE package carries."""
        self._require_link()
        q = self._reading()
        return q, self.model.flange_pose(q)

    def controller_flange_pose(self) -> np.ndarray:
        """``T_base_flange`` as the controller reports it (its FK of a fresh joint reading)."""
        return self.joints_and_controller_pose()[1]

    def true_flange_pose(self) -> np.ndarray:
        """Where the flange physically is now (true kinematics of the true, ringing joints,
        and what the controller's calibration leaves of the pose error, the profile's
        ``residual``); what the mock camera renders from. Nothing a real arm could report."""
        self._require_link()
        q = self._true_q()
        if self._residual is None:
            return self.model.flange_pose(q)
        return self.model.flange_pose(q) @ self._residual.at(q)

    def wait_until_steady(self, timeout: float = 10.0) -> None:
        """Moves block until the arm stops; with ringing, wait (on the clock) until it is
        below STEADY_RAD, as a controller's isSteady does."""
        self.history.append(("wait_until_steady", {"timeout": timeout}))
        _check_positive(timeout, "timeout", math.inf, "s", self.name)
        self._require_link()
        ring = self.profile.joints
        if self._ring_start_ns is None or ring.settle_amplitude_rad <= STEADY_RAD:
            return
        quiet_s = ring.settle_time_constant_s * math.log(ring.settle_amplitude_rad / STEADY_RAD)
        left = (self._ring_start_ns - self.clock.now_ns()) * 1e-9 + quiet_s
        if left > timeout:
            raise MotionTimeout(f"{self.name}: not steady within {timeout:g} s")
        if left > 0:
            self.clock.sleep(left)

    def _true_q(self) -> np.ndarray:
        """The true joints now: the resting joints plus the decaying ringing of the last move."""
        ring = self.profile.joints
        if self._ring_start_ns is None or ring.settle_amplitude_rad <= 0:
            return self._q.copy()
        dt = max(0.0, (self.clock.now_ns() - self._ring_start_ns) * 1e-9)
        envelope = ring.settle_amplitude_rad * math.exp(-dt / ring.settle_time_constant_s)
        return self._q + envelope * math.sin(2 * math.pi * ring.settle_frequency_hz * dt) \
            * self._ring_shape

    def _reading(self) -> np.ndarray:
        noise = self.profile.joints.encoder_noise_rad
        q = self._true_q()
        return q + self._joint_rng.normal(0.0, noise, 6) if noise > 0 else q

    def stop(self) -> None:
        """Stop now; never raises (a stop on a dropped link is only logged)."""
        self.history.append(("stop", {}))
        if not self._connected:
            self.events.append("stop requested without a link")
            log.info("%s: stop requested while not connected", self.name)

    # -- motion ----------------------------------------------------------------------------

    def move_joints(self, q: np.ndarray, speed: float, acceleration: float,
                    timeout: float = 60.0) -> None:
        """Joint move to ``q`` (rad): synchronised trapezoid at ``speed`` rad/s (capped per
        joint by the model's velocity limits) and ``acceleration`` rad/s^2."""
        self.history.append(("move_joints", {"q": _snapshot(q), "speed": speed,
                                             "acceleration": acceleration, "timeout": timeout}))
        target = _check_q(q, "q", self.name)
        _check_positive(speed, "joint speed", MAX_JOINT_SPEED, "rad/s", self.name)
        _check_positive(acceleration, "joint acceleration", MAX_JOINT_ACCELERATION, "rad/s^2",
                        self.name)
        _check_positive(timeout, "timeout", math.inf, "s", self.name)
        self._require_ready()
        self.model.check_limits(target)
        delta = target - self._q
        span = float(np.max(np.abs(delta)))
        n = max(1, math.ceil(span / JOINT_STEP_RAD))
        sigma = np.arange(n + 1) / n
        qs = self._q + sigma[:, None] * delta
        qs[-1] = target
        # One normalised profile for all joints; each joint's speed cap scales it.
        with np.errstate(divide="ignore"):
            v = float(np.min(np.minimum(speed, self.model.velocity_limits) / np.abs(delta)))
            a = float(np.min(acceleration / np.abs(delta)))
        times = trapezoid_time_at(sigma, 1.0, v, a) if span > 0 else np.zeros(n + 1)
        self._execute("move_joints", qs, times, timeout)

    def move_linear(self, T_base_flange: np.ndarray, speed: float, acceleration: float,
                    timeout: float = 60.0) -> None:
        """Straight-line flange move to ``T_base_flange`` (base frame): trapezoid in path
        length at ``speed`` m/s and ``acceleration`` m/s^2, orientation slerped (capped at
        LINEAR_ROTATION_SPEED). Raises IKError before moving if any path sample has no IK."""
        self.history.append(("move_linear", {"T_base_flange": _snapshot(T_base_flange),
                                             "speed": speed, "acceleration": acceleration,
                                             "timeout": timeout}))
        target = _check_pose(T_base_flange, self.name)
        _check_positive(speed, "linear speed", MAX_LINEAR_SPEED, "m/s", self.name)
        _check_positive(acceleration, "linear acceleration", MAX_LINEAR_ACCELERATION, "m/s^2",
                        self.name)
        _check_positive(timeout, "timeout", math.inf, "s", self.name)
        self._require_ready()
        start = self.model.flange_pose(self._q)
        dist = float(np.linalg.norm(target[:3, 3] - start[:3, 3]))
        rotvec = matrix_to_rotvec(start[:3, :3].T @ target[:3, :3])
        angle = float(np.linalg.norm(rotvec))
        n = max(1, math.ceil(dist / PATH_STEP_M), math.ceil(angle / PATH_STEP_RAD))
        sigma = np.arange(n + 1) / n
        qs = self._linear_path_ik(start, target, rotvec, sigma)
        # The slower of the translation and rotation profiles sets the normalised profile.
        v = min(speed / dist if dist > 0 else math.inf,
                LINEAR_ROTATION_SPEED / angle if angle > 0 else math.inf)
        a = min(acceleration / dist if dist > 0 else math.inf,
                LINEAR_ROTATION_ACCELERATION / angle if angle > 0 else math.inf)
        times = trapezoid_time_at(sigma, 1.0, v, a) if math.isfinite(v) else np.zeros(n + 1)
        self._execute("move_linear", qs, self._respect_joint_speeds(qs, times), timeout)

    def _linear_path_ik(self, start: np.ndarray, target: np.ndarray, rotvec: np.ndarray,
                        sigma: np.ndarray) -> np.ndarray:
        """Joints (n+1, 6) along the straight path, IK warm-started from the previous sample."""
        qs = np.empty((len(sigma), 6))
        qs[0] = self._q
        for k in range(1, len(sigma)):
            T = target if k == len(sigma) - 1 else make_T(
                start[:3, :3] @ rotvec_to_matrix(sigma[k] * rotvec),
                start[:3, 3] + sigma[k] * (target[:3, 3] - start[:3, 3]))
            try:
                qs[k] = self.model.ik(T, qs[k - 1])
            except IKError as err:
                raise IKError(f"{self.name}: linear move refused before moving: no IK at "
                              f"{sigma[k]:.0%} of the path ({err})", err.reason) from None
            jump = float(np.max(np.abs(qs[k] - qs[k - 1])))
            if jump > MAX_SAMPLE_JUMP_RAD:
                raise IKError(f"{self.name}: linear move refused before moving: joints jump "
                              f"{jump:.2f} rad at {sigma[k]:.0%} of the path (limit "
                              f"{MAX_SAMPLE_JUMP_RAD} rad; IK branch flip near a singularity)",
                              "branch_flip")
        return qs

    def _respect_joint_speeds(self, qs: np.ndarray, times: np.ndarray) -> np.ndarray:
        """Stretch path segments whose joint speeds would exceed the model's limits."""
        dt = np.diff(times)
        need = np.max(np.abs(np.diff(qs, axis=0)) / self.model.velocity_limits, axis=1)
        return np.concatenate([[0.0], np.cumsum(np.maximum(dt, need))])

    def _execute(self, kind: str, qs: np.ndarray, times: np.ndarray, timeout: float) -> None:
        """Play the sampled path on the clock; inject a due fault; apply joint noise."""
        self.moves_started += 1
        n = self.moves_started
        fault = self.faults.move_fault(n)
        duration = float(times[-1])
        halt = min(FAULT_FRACTION * duration if fault is not None else duration, timeout)
        reached = self._play(qs, times, halt)
        self.last_move_duration = halt
        if fault is not None:
            self._fail(fault, kind, n, reached, timeout)
        if halt < duration:
            self._halted(f"move {n} ({kind}) timed out at {reached:.0%} of its path")
            raise MotionTimeout(f"{self.name}: move {n} ({kind}) needs {duration:.2f} s, more "
                                f"than the {timeout:g} s timeout; stopped at {reached:.0%} of "
                                f"the path")
        self.commanded_q = qs[-1].copy()
        if self._residual is not None:
            self._residual.moved()
        if self.joint_noise > 0:
            noisy = qs[-1] + self._rng.normal(0.0, self.joint_noise, 6)
            self._q = np.clip(noisy, self.model.lower, self.model.upper)
        if self.profile.joints.settle_amplitude_rad > 0:
            # Each move excites its own mix of the joints; largest component = amplitude.
            shape = self._joint_rng.standard_normal(6)
            self._ring_shape = shape / np.max(np.abs(shape))
            self._ring_start_ns = self.clock.now_ns()

    def _play(self, qs: np.ndarray, times: np.ndarray, until: float) -> float:
        """Advance the clock along the samples up to time ``until`` (s after the start); the
        arm holds the last sample reached. Returns the fraction of the path (in samples)
        completed. Sleeps target absolute times, so rounding never accumulates."""
        start = self.clock.now_ns()
        k_last = 0
        for k in range(1, len(qs)):
            if times[k] > until:
                break
            self._sleep_until(start, times[k])
            self._q = qs[k].copy()
            k_last = k
        self._sleep_until(start, until)
        return k_last / (len(qs) - 1)

    def _sleep_until(self, start_ns: int, t: float) -> None:
        self.clock.sleep((start_ns + round(t * 1e9) - self.clock.now_ns()) * 1e-9)

    def _fail(self, fault: Fault, kind: str, n: int, reached: float, timeout: float) -> NoReturn:
        where = f"during move {n} ({kind}, stopped at {reached:.0%} of the path)"
        self._halted(f"injected {fault} {where}")
        if fault.name == "disconnect":
            self._connected, self._lost = False, True
            self._state, self._detail = ArmState.DISCONNECTED, f"connection lost {where}"
            raise ConnectionLost(f"{self.name}: connection lost {where} (injected {fault})")
        if fault.name == "protective-stop":
            self._state, self._detail = ArmState.PROTECTIVE_STOP, f"protective stop {where}"
            raise ProtectiveStop(f"{self.name}: protective stop {where} (injected {fault})")
        # stuck-move: the arm never arrives; the caller's timeout expires.
        self.clock.sleep(max(0.0, timeout - self.last_move_duration))
        self.last_move_duration = max(timeout, self.last_move_duration)
        raise MotionTimeout(f"{self.name}: move {n} ({kind}) did not finish within the "
                            f"{timeout:g} s timeout; stuck at {reached:.0%} of the path "
                            f"(injected {fault})")

    def _halted(self, what: str) -> None:
        self.events.append(what)
        log.info("%s: %s", self.name, what)

    def _require_link(self) -> None:
        if self._lost:
            raise ConnectionLost(f"{self.name}: {self._detail}; reconnect first")
        self._require_connected()

    def _require_ready(self) -> None:
        self._require_link()
        if self._state is ArmState.PROTECTIVE_STOP:
            raise ProtectiveStop(f"{self.name}: in protective stop ({self._detail}); unlock "
                                 f"it before moving")


def _snapshot(x):
    """A copy of a call argument for :attr:`MockArm.history` (as given if not numeric)."""
    try:
        return np.array(x, dtype=float)
    except (TypeError, ValueError):
        return x


def _as_float_array(x, what: str, name: str) -> np.ndarray:
    try:
        return np.asarray(x, dtype=float)
    except (TypeError, ValueError):
        raise ConfigError(f"{name}: {what} must be numeric, got {x!r}") from None


def _check_q(q, what: str, name: str) -> np.ndarray:
    q = _as_float_array(q, what, name)
    if q.shape != (6,) or not np.all(np.isfinite(q)):
        raise ConfigError(f"{name}: {what} must be 6 finite joint angles (rad), got shape "
                          f"{q.shape}")
    return q.copy()


def _check_pose(T, name: str) -> np.ndarray:
    return as_rigid(T, f"{name}: target T_base_flange")


def _check_positive(value: float, what: str, limit: float, unit: str, name: str) -> None:
    positive(value, f"{name}: {what}", unit, cap=None if math.isinf(limit) else limit)


def _true_kinematics(model: ArmModel, profile: MockProfile, seed: int):
    """(the arm's true ArmModel, its DH table or None): a seeded factory calibration of
    ``model``'s type when the profile says so, else ``model`` itself (no broadcast)."""
    if not profile.kinematics:
        return model, None
    from armstereo.kinematics import ArmModel as _ArmModel
    from armstereo.robot.synthetic import synthetic_calibration

    table = synthetic_calibration(model.name, seed)
    return _ArmModel.from_dh(table, mount=model.mount), table
