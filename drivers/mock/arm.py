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
    """

    def __init__(self, model: ArmModel, q0: np.ndarray | None = None, *,
                 clock: Clock | None = None, realtime: bool = False, joint_noise: float = 0.0,
                 seed: int = 0, faults: FaultPlan | None = None, name: str = "mock arm"):
        if realtime and isinstance(clock, SimClock):
            raise ConfigError(f"{name}: realtime=True needs a real clock, not a SimClock")
        if not (math.isfinite(joint_noise) and joint_noise >= 0):
            raise ConfigError(f"{name}: joint_noise must be >= 0 rad, got {joint_noise}")
        self.model = model
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
                   seed=config.seed, faults=config.fault_plan)

    # -- connection ------------------------------------------------------------------------

    def connect(self) -> None:
        """Open the simulated link (also after a lost one: the arm kept its joints)."""
        self.history.append(("connect", {}))
        self._require_not_connected()
        self._connected, self._lost = True, False
        if self._state is ArmState.DISCONNECTED:
            self._state, self._detail = ArmState.NORMAL, ""

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
        """Actual joints (6,), radians (with the repeatability noise of the last move)."""
        self._require_link()
        return self._q.copy()

    def wait_until_steady(self, timeout: float = 10.0) -> None:
        """Moves block until the arm is at rest, so the mock is always steady here."""
        self.history.append(("wait_until_steady", {"timeout": timeout}))
        _check_positive(timeout, "timeout", math.inf, "s", self.name)
        self._require_link()

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
        if self.joint_noise > 0:
            noisy = qs[-1] + self._rng.normal(0.0, self.joint_noise, 6)
            self._q = np.clip(noisy, self.model.lower, self.model.upper)

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
