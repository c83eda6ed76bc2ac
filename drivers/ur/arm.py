"""A Universal Robots arm through ur_rtde: RTDEReceiveInterface for state, RTDEControlInterface
for motion, the dashboard server only to release a protective stop on request.

Frames and units: joints in radians (UR order), Cartesian targets ``T_base_flange`` (4x4, metres)
in the controller's ``base`` frame. The TCP is set to zero at connect, so the controller's
``getActualTCPPose`` is the flange pose; it is checked once against the model's local FK.

How ur_rtde's traps are avoided:

- Connect: :func:`drivers.ur.probe.check_controller` does the RTDE handshake with timeouts
  before ur_rtde's constructors (which have none); the receive interface opens first, the
  safety state is checked, and only then the control interface uploads its script.
- Moves are asynchronous and polled here with our own deadline and link, data-freshness and
  safety checks; on any error the arm gets stopL/stopJ before the error propagates.
- Every control call goes through :class:`ControlChannel`: serialised (the interface is not
  thread-safe) and with a deadline (a command on a dead link can otherwise block for 300 s).
- Joint readings wait for two new RTDE packages (the state right after a move can be one period
  stale) and keep the controller timestamp they belong to.
- Kinematics are local (ArmModel); ``getForwardKinematics`` is never used (stale registers).
  At connect the controller's own calibrated DH table is read from its read-only primary
  interface (:mod:`drivers.ur.primary`) and, when read, replaces the model's kinematics.

:class:`URArm` is the life cycle and the motion; the connect steps and the dashboard unlock are
in :mod:`drivers.ur.connect`, the readings of the receive interface in
:mod:`drivers.ur.readings` (parts of the same class).
"""

from __future__ import annotations

import logging
from typing import TYPE_CHECKING

import numpy as np

from armstereo.clock import Clock, RealClock
from armstereo.devices import (
    MAX_JOINT_ACCELERATION,
    MAX_JOINT_SPEED,
    MAX_LINEAR_ACCELERATION,
    MAX_LINEAR_SPEED,
    Arm,
    ArmState,
    ArmStatus,
)
from armstereo.errors import (
    ConfigError,
    ConnectionLost,
    EmergencyStop,
    HardwareError,
    MotionTimeout,
    NotConnected,
    ProtectiveStop,
)
from armstereo.robot.dh import NOMINAL_MODELS
from armstereo.transforms import T_from_ur_pose, as_rigid, ur_pose_from_T
from armstereo.validate import host as validate_host
from armstereo.validate import positive
from drivers.ur.channel import ControlChannel
from drivers.ur.connect import ConnectSteps, import_ur_rtde, pose_error
from drivers.ur.primary import read_arm_kinematics
from drivers.ur.probe import DASHBOARD_PORT, ControllerInfo, check_controller, check_port
from drivers.ur.readings import DataWatch, Readings
from drivers.ur.safety import ControllerState

if TYPE_CHECKING:
    from armstereo.robot.arm_model import ArmModel
    from drivers.ur.config import URArmConfig

log = logging.getLogger(__name__)

POLL_S = 0.01               # motion / steadiness polling period
DATA_TIMEOUT_S = 1.0        # no new RTDE package for this long = link lost
CALL_TIMEOUT_S = 5.0        # one ur_rtde control call (commands answer within a few periods)
STOP_CALL_TIMEOUT_S = 2.0   # stopL/stopJ/stopScript while cleaning up
CLOSE_CALL_TIMEOUT_S = 3.0  # ur_rtde's disconnect() sleeps 0.5 s
STOPL_DECELERATION = 5.0    # m/s^2: stops a 0.25 m/s move within 6 mm
STOPJ_DECELERATION = 4.0    # rad/s^2: stops a 1 rad/s move within 0.13 rad
SETTLED_TOL = (2e-4, 2e-3)  # (m, rad) at the target + isSteady counts as done (progress fallback)
REACHED_TOL = (1e-3, 1e-2)  # (m, rad) a finished move must end this close to its target
_STOP_ERRORS = {ArmState.PROTECTIVE_STOP: ProtectiveStop, ArmState.EMERGENCY_STOP: EmergencyStop}


class URArm(ConnectSteps, Readings, Arm):
    """A UR arm (CB3, e-Series) through ur_rtde.

    ``host``: controller IP or name. ``model``: the arm's ArmModel (local FK). ``connect_timeout``:
    seconds for each connection step we can bound (ur_rtde's own constructors cannot be).
    ``frequency``: RTDE rate in Hz, -1 for the controller's (125 CB3 / 500 e-Series).
    ``upper_range_registers``: use input registers 24-47 (coexists with a fieldbus or another
    RTDE client). ``clock``: timestamps, sleeps and deadlines (default RealClock).

    Attributes after a joint reading: ``last_controller_timestamp`` (s, controller clock) and
    ``last_host_timestamp_ns``. After connect: ``controller`` (ControllerInfo),
    ``kinematics`` (``drivers.ur.primary.ArmKinematics``: the controller's calibrated table, or
    the nominal one with warnings when it could not be read), ``model`` (the model given, or,
    when the table was read, the calibrated model built from it with the given mount) and
    ``fk_mismatch`` (m, rad) between the controller's flange pose and the model's FK.
    """

    name = "ur"

    def __init__(self, host: str, model: ArmModel, *, connect_timeout: float = 2.0,
                 frequency: float = -1.0, upper_range_registers: bool = False,
                 clock: Clock | None = None):
        self.host = _check_host(host)
        if not (np.isfinite(connect_timeout) and connect_timeout > 0):
            raise ConfigError(f"connect_timeout must be positive seconds, got {connect_timeout!r}")
        if frequency != -1.0 and not (0 < frequency <= 500):
            raise ConfigError(f"RTDE frequency must be -1 (controller default) or in (0, 500] Hz, "
                              f"got {frequency!r}")
        self.model = model
        self.connect_timeout = float(connect_timeout)
        self.frequency = float(frequency)
        self.upper_range_registers = bool(upper_range_registers)
        self.clock = clock if clock is not None else RealClock()
        self.name = f"UR arm at {self.host}"
        self.controller: ControllerInfo | None = None
        self.kinematics = None
        self.fk_mismatch: tuple[float, float] | None = None
        self.last_controller_timestamp: float | None = None
        self.last_host_timestamp_ns: int | None = None
        # Tunables (instance attributes so tests and special setups can tighten them).
        self.poll_interval = POLL_S
        self.data_timeout = DATA_TIMEOUT_S
        self.call_timeout = CALL_TIMEOUT_S
        self.stop_timeout = STOP_CALL_TIMEOUT_S
        self._rr = None
        self._ch: ControlChannel | None = None
        self._connected = False
        self._stop_command = "stopL"

    @classmethod
    def from_config(cls, config: URArmConfig, model: ArmModel) -> URArm:
        """The registry's constructor (see :mod:`armstereo.backends`)."""
        return cls(config.host, model, upper_range_registers=config.upper_range_registers)

    def __repr__(self) -> str:
        return f"URArm({self.host!r}, {getattr(self.model, 'name', self.model)!r})"

    # ----------------------------------------------------------------------------- life cycle
    def connect(self) -> None:
        """Probe, open receive, check safety, open control, zero the TCP, cross-check FK.

        Raises ConnectionFailed (naming the host and a remedy), ProtectiveStop / EmergencyStop
        (the controller is stopped; nothing is uploaded), ConfigError (ur_rtde missing, or the
        controller's flange pose is far from this model's FK). A failed connect leaves nothing
        open.
        """
        self._require_not_connected()
        rtde_control, rtde_receive, _ = import_ur_rtde()
        self.controller = check_controller(self.host, self.connect_timeout)
        log.info("UR controller at %s: %s", self.host, self.controller)
        self._read_calibrated_kinematics()
        try:
            self._rr = self._open_receive(rtde_receive)
            self._connected = True
            self._check_safe_to_connect()
            self._ch = ControlChannel(self._open_control(rtde_control), self.host)
            self._set_zero_tcp()
            self._cross_check_kinematics()
        except BaseException:
            self.close()
            raise

    def close(self) -> None:
        """Stop, end the control script, disconnect both interfaces. Idempotent, never raises."""
        ch, rr = self._ch, self._rr
        self._ch = self._rr = None
        self._connected = False
        if ch is not None:
            self._stop_quietly(ch, self._stop_command)
            self._quiet_call(ch, "stopScript", self.stop_timeout)
            self._quiet_call(ch, "disconnect", CLOSE_CALL_TIMEOUT_S)
            ch.close()
        if rr is not None:
            try:
                rr.disconnect()
            except Exception as err:  # noqa: BLE001 - closing must not raise
                log.warning("%s: receive disconnect failed: %s", self.name, err)

    @property
    def is_connected(self) -> bool:
        if not self._connected or self._rr is None or self._ch is None:
            return False
        try:
            return bool(self._rr.isConnected()) and bool(
                self._ch.call("isConnected", timeout=self.stop_timeout))
        except Exception:  # noqa: BLE001 - a property answers, it does not raise
            return False

    def _read_calibrated_kinematics(self) -> None:
        """Read the controller's DH table (read-only port); use it when it was read."""
        name = str(getattr(self.model, "name", "")).lower()
        expected = name if name in NOMINAL_MODELS else None
        self.kinematics = read_arm_kinematics(self.host, expected, timeout=self.connect_timeout)
        for note in self.kinematics.warnings:
            log.info("UR controller at %s: %s", self.host, note)
        if self.kinematics.calibrated:
            from armstereo.robot.arm_model import ArmModel

            self.model = ArmModel.from_dh(self.kinematics.table,
                                          mount=getattr(self.model, "mount", None))

    # ------------------------------------------------------------------------------- reading
    def joint_positions(self) -> np.ndarray:
        """Actual joints (6,) rad, from a package that arrived after this call began.

        Sets ``last_controller_timestamp`` (s, controller clock) and ``last_host_timestamp_ns``.
        Raises ConnectionLost if the link is down or no data arrives.
        """
        self._require_connected()
        s = self._fresh_sample()
        self.last_controller_timestamp = s.controller_time
        self.last_host_timestamp_ns = self.clock.now_ns()
        return s.q.copy()

    def joints_and_controller_pose(self) -> tuple[np.ndarray, np.ndarray]:
        """Actual joints (6,) rad and the controller's ``T_base_flange`` (4x4, m; TCP pose with
        the zero TCP set at connect) from ONE fresh RTDE package, so they belong together.
        Sets the timestamps as :meth:`joint_positions` does."""
        self._require_connected()
        s = self._fresh_sample()
        self.last_controller_timestamp = s.controller_time
        self.last_host_timestamp_ns = self.clock.now_ns()
        return s.q.copy(), T_from_ur_pose(s.tcp_pose)

    def controller_flange_pose(self) -> np.ndarray:
        """``T_base_flange`` (4x4, m) as the controller reports it (getActualTCPPose with the zero
        TCP set at connect), from a fresh package. For cross-checks: captures use local FK."""
        self._require_connected()
        return T_from_ur_pose(self._fresh_sample().tcp_pose)

    def status(self) -> ArmStatus:
        """Connection and safety state with the controller's mode names; never raises."""
        if not self._connected or self._rr is None:
            return ArmStatus(ArmState.DISCONNECTED, "not connected")
        try:
            if not self._rr.isConnected():
                return ArmStatus(ArmState.DISCONNECTED, f"RTDE link to {self.host} lost")
            if self._ch is not None and not self._ch.call("isConnected",
                                                          timeout=self.stop_timeout):
                return ArmStatus(ArmState.DISCONNECTED, f"control link to {self.host} lost")
            st = self._read_state()
        except Exception as err:  # noqa: BLE001 - status reports, it does not raise
            return ArmStatus(ArmState.DISCONNECTED, f"cannot read the state of {self.host}: {err}")
        return ArmStatus(st.arm_state(), st.describe())

    # -------------------------------------------------------------------------------- motion
    def move_linear(self, T_base_flange: np.ndarray, speed: float, acceleration: float,
                    timeout: float = 60.0) -> None:
        """Straight-line flange move (moveL) to ``T_base_flange`` (base frame, m), speed m/s,
        acceleration m/s^2. Raises ConfigError before any call for caps or a non-rigid target;
        ConnectionLost / ProtectiveStop / EmergencyStop / MotionTimeout / HardwareError after
        stopping the arm."""
        _check_cap("move_linear speed", speed, MAX_LINEAR_SPEED, "m/s")
        _check_cap("move_linear acceleration", acceleration, MAX_LINEAR_ACCELERATION, "m/s^2")
        _check_timeout(timeout)
        T = _rigid(T_base_flange)
        self._move("moveL", ur_pose_from_T(T), speed, acceleration, timeout,
                   lambda s: pose_error(T, s.tcp_pose))

    def move_joints(self, q: np.ndarray, speed: float, acceleration: float,
                    timeout: float = 60.0) -> None:
        """Joint-space move (moveJ) to ``q`` (rad) at ``speed`` rad/s, ``acceleration`` rad/s^2.
        Refuses caps and joint limits (model) before any call; errors as move_linear."""
        _check_cap("move_joints speed", speed, MAX_JOINT_SPEED, "rad/s")
        _check_cap("move_joints acceleration", acceleration, MAX_JOINT_ACCELERATION, "rad/s^2")
        _check_timeout(timeout)
        target = np.asarray(q, dtype=float).reshape(-1)
        if target.shape != (6,) or not np.all(np.isfinite(target)):
            raise ConfigError(f"move_joints needs 6 finite joint angles (rad), got {q!r}")
        self.model.check_limits(target)
        self._move("moveJ", target, speed, acceleration, timeout,
                   lambda s: (0.0, float(np.max(np.abs(s.q - target)))))

    def wait_until_steady(self, timeout: float = 10.0) -> None:
        """Block until the controller says the arm is at rest (isSteady) and two newer RTDE
        packages arrived; MotionTimeout after ``timeout`` s. Stops the arm on any error."""
        self._require_connected()
        _check_timeout(timeout)
        context = " while waiting for the arm to settle"
        try:
            start, watch = self.clock.now(), DataWatch(self)
            while True:
                self._check_link(context)
                self._raise_if_stopped(context)
                watch.check()
                if self._call("isSteady"):
                    self._wait_fresh()
                    return
                if self.clock.now() - start > timeout:
                    raise MotionTimeout(f"UR arm at {self.host} was not steady within "
                                        f"{timeout:g} s (still moving, or in freedrive, teach or "
                                        f"force mode?)")
                self.clock.sleep(self.poll_interval)
        except BaseException:
            self._stop_quietly(self._ch, self._stop_command)
            raise

    def stop(self) -> None:
        """stopL/stopJ (matching the last move) now; never raises."""
        self._stop_quietly(self._ch, self._stop_command)

    def recover_protective_stop(self, timeout: float = 15.0) -> None:
        """Release a protective stop through the dashboard server, then (when connected) restart
        ur_rtde's control script and zero the TCP again. Never called automatically: only after
        whatever caused the stop has been cleared. Raises ConnectionFailed (dashboard
        unreachable), ProtectiveStop (unlock refused for ``timeout`` s), HardwareError."""
        _check_timeout(timeout)
        _, _, dashboard_client = import_ur_rtde()
        if self._connected:
            st = self._read_state()
            if st.emergency_stopped:
                raise EmergencyStop(f"UR controller at {self.host} is in an emergency stop or "
                                    f"fault ({st.describe()}), which no unlock can release")
            if not st.protective_stopped:
                log.info("UR controller at %s is not in a protective stop", self.host)
                return
        check_port(self.host, DASHBOARD_PORT, self.connect_timeout, "dashboard server")
        self._unlock_via_dashboard(dashboard_client, timeout)
        if self._connected:
            self._resume_control(timeout)
        log.info("UR controller at %s: protective stop released", self.host)

    # ------------------------------------------------------------------------------- helpers
    def _move(self, command: str, target, speed: float, acceleration: float, timeout: float,
              error_of) -> None:
        """Send an asynchronous ``command`` and poll it to the end; stop on any error."""
        self._require_connected()
        self._stop_command = "stopL" if command == "moveL" else "stopJ"
        try:
            self._check_link(f" before {command}")
            self._raise_if_stopped(f" before {command}")
            before = int(self._call("getAsyncOperationProgress"))
            if not self._call(command, [float(v) for v in target], float(speed),
                              float(acceleration), asynchronous=True):
                self._raise_refused(command)
            self._await_motion(command, before, timeout, error_of)
            self._verify_reached(command, error_of)
        except BaseException:
            self._stop_quietly(self._ch, self._stop_command)
            raise

    def _await_motion(self, command: str, before: int, timeout: float, error_of) -> None:
        """Poll until the async operation ends (or the arm rests at the target), checking link,
        data freshness and safety on every round."""
        context = f" during {command}"
        start, watch = self.clock.now(), DataWatch(self)
        seen_running = False
        while True:
            self._check_link(context)
            self._raise_if_stopped(context)
            watch.check()
            # >= 0 while running; < 0 when idle, toggling between -1 and -2 per operation, so a
            # change from the value before the command also means "finished" (short moves).
            progress = int(self._call("getAsyncOperationProgress"))
            if progress >= 0:
                seen_running = True
            # Progress reporting is known to stick on some setups: at the target and steady is
            # done too.
            if (progress < 0 and (seen_running or progress != before)
                    or self._settled_at_target(error_of)):
                # A stop also ends the operation: look again before calling it finished.
                self._check_link(context)
                self._raise_if_stopped(context)
                return
            if self.clock.now() - start > timeout:
                raise MotionTimeout(f"{command} on UR controller at {self.host} did not finish "
                                    f"within {timeout:g} s{self._slider_note()}")
            self.clock.sleep(self.poll_interval)

    def _settled_at_target(self, error_of) -> bool:
        lin, ang = error_of(self._read_sample())
        return lin <= SETTLED_TOL[0] and ang <= SETTLED_TOL[1] and bool(self._call("isSteady"))

    def _verify_reached(self, command: str, error_of) -> None:
        lin, ang = error_of(self._fresh_sample())
        if lin > REACHED_TOL[0] or ang > REACHED_TOL[1]:
            self._raise_if_stopped(f" after {command}")
            raise HardwareError(
                f"{command} on UR controller at {self.host} ended {lin * 1000:.2f} mm / "
                f"{np.degrees(ang):.2f} deg from its target (allowed {REACHED_TOL[0] * 1000:g} mm "
                f"/ {np.degrees(REACHED_TOL[1]):.2f} deg): was it stopped?")

    def _raise_refused(self, command: str) -> None:
        st = self._read_state()
        self._raise_if_stopped(f" (it refused {command})", st)
        if not st.program_running:
            raise HardwareError(f"UR controller at {self.host} refused {command}: ur_rtde's "
                                f"control script is not running ({st.describe()}); reconnect")
        raise HardwareError(f"UR controller at {self.host} refused {command} ({st.describe()})")

    def _slider_note(self) -> str:
        try:
            fraction = float(self._rr.getTargetSpeedFraction())
        except Exception:  # noqa: BLE001 - only decorates a message
            return ""
        return f" (speed slider at {fraction * 100:.0f} %)" if fraction < 0.999 else ""

    def _call(self, method: str, *args, timeout: float | None = None, **kwargs):
        """One control-interface call through the channel (serialised, with a deadline)."""
        if self._ch is None:
            raise NotConnected(f"{self.name}: not connected; call connect() first")
        return self._ch.call(method, *args, timeout=self.call_timeout if timeout is None
                             else timeout, **kwargs)

    def _stop_quietly(self, ch: ControlChannel | None, command: str) -> None:
        deceleration = STOPL_DECELERATION if command == "stopL" else STOPJ_DECELERATION
        if ch is not None:
            self._quiet_call(ch, command, self.stop_timeout, deceleration)

    def _quiet_call(self, ch: ControlChannel, method: str, timeout: float, *args) -> None:
        try:
            ch.call(method, *args, timeout=timeout)
        except Exception as err:  # noqa: BLE001 - cleanup must not hide the original error
            log.warning("%s (while stopping or closing)", err)  # names host and method

    def _check_link(self, context: str = "") -> None:
        if not self._rr_get("isConnected"):
            raise ConnectionLost(f"lost the RTDE connection to UR controller at {self.host}"
                                 f"{context}")
        if self._ch is not None and not self._call("isConnected"):
            raise ConnectionLost(f"lost the control connection to UR controller at {self.host}"
                                 f"{context}")

    def _raise_if_stopped(self, context: str, st: ControllerState | None = None) -> None:
        st = self._read_state() if st is None else st
        kind = st.arm_state()
        if kind is ArmState.NORMAL:
            return
        what = ("is in an emergency stop or safety fault" if st.emergency_stopped
                else "is in a protective stop" if st.protective_stopped
                else "has the arm not running")
        raise _STOP_ERRORS[kind](f"UR controller at {self.host} {what}{context} "
                                 f"({st.describe()})")

def _check_host(host) -> str:
    return validate_host(host, "UR host")


def _check_cap(what: str, value: float, cap: float, unit: str) -> None:
    positive(value, what, unit, cap=cap)


def _check_timeout(timeout: float) -> None:
    positive(timeout, "timeout", "s")


def _rigid(T) -> np.ndarray:
    return as_rigid(T, "move_linear target T_base_flange")
