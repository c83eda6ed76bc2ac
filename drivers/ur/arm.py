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
"""

from __future__ import annotations

import logging
from typing import TYPE_CHECKING, NamedTuple

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
    ArmstereoError,
    ConfigError,
    ConnectionFailed,
    ConnectionLost,
    EmergencyStop,
    HardwareError,
    MotionTimeout,
    NotConnected,
    ProtectiveStop,
)
from armstereo.robot.dh import NOMINAL_MODELS
from armstereo.transforms import T_from_ur_pose, as_rigid, matrix_to_rotvec, ur_pose_from_T
from armstereo.validate import host as validate_host
from armstereo.validate import positive
from drivers.ur.channel import ControlChannel
from drivers.ur.diagnose import connection_failed
from drivers.ur.primary import read_arm_kinematics
from drivers.ur.probe import DASHBOARD_PORT, ControllerInfo, check_controller, check_port
from drivers.ur.safety import ControllerState

if TYPE_CHECKING:
    from armstereo.robot.arm_model import ArmModel
    from drivers.ur.config import URArmConfig

log = logging.getLogger(__name__)

# The only RTDE outputs the receive interface subscribes (an explicit list keeps the recipe
# small and names exactly what a controller, or the test emulator, must provide).
RECEIVE_VARIABLES = ("timestamp", "actual_q", "actual_TCP_pose", "robot_mode", "safety_mode",
                     "safety_status_bits", "runtime_state", "target_speed_fraction")

POLL_S = 0.01               # motion / steadiness polling period
FRESH_POLL_S = 0.001        # polling period while waiting for new RTDE packages
FRESH_PACKAGES = 2          # packages that must arrive after a call before its reading
DATA_TIMEOUT_S = 1.0        # no new RTDE package for this long = link lost
CALL_TIMEOUT_S = 5.0        # one ur_rtde control call (commands answer within a few periods)
STOP_CALL_TIMEOUT_S = 2.0   # stopL/stopJ/stopScript while cleaning up
CLOSE_CALL_TIMEOUT_S = 3.0  # ur_rtde's disconnect() sleeps 0.5 s
STOPL_DECELERATION = 5.0    # m/s^2: stops a 0.25 m/s move within 6 mm
STOPJ_DECELERATION = 4.0    # rad/s^2: stops a 1 rad/s move within 0.13 rad
SETTLED_TOL = (2e-4, 2e-3)  # (m, rad) at the target + isSteady counts as done (progress fallback)
REACHED_TOL = (1e-3, 1e-2)  # (m, rad) a finished move must end this close to its target
FK_WARN_TOL = (1e-3, 2e-3)          # controller vs model FK: calibration differs, warn
# With the controller's own table, FK reproduces its pose to ~1e-12 m: more than this means the
# table is not this arm's (the per-view check in recordings uses the same 0.1 mm).
FK_CALIBRATED_WARN_TOL = (1e-4, 1e-4)
FK_WRONG_MODEL_TOL = (0.02, 0.05)   # controller vs model FK: not this robot model, refuse
UNLOCK_RETRY_S = 0.5        # dashboard refuses an unlock within 5 s of the stop; retry

_STOP_ERRORS = {ArmState.PROTECTIVE_STOP: ProtectiveStop, ArmState.EMERGENCY_STOP: EmergencyStop}


class _Sample(NamedTuple):
    """One consistent RTDE reading: controller time (s), joints (rad), TCP pose (UR 6-vector)."""

    controller_time: float
    q: np.ndarray
    tcp_pose: np.ndarray


class URArm(Arm):
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
        rtde_control, rtde_receive, _ = _import_ur_rtde()
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

    def _open_receive(self, rtde_receive):
        try:
            return rtde_receive.RTDEReceiveInterface(
                self.host, frequency=self.frequency, variables=list(RECEIVE_VARIABLES),
                verbose=False, use_upper_range_registers=self.upper_range_registers)
        except Exception as err:
            raise connection_failed(self.host, "receive", err) from err

    def _open_control(self, rtde_control):
        rc = rtde_control.RTDEControlInterface
        flags = int(rc.FLAG_UPLOAD_SCRIPT)
        if self.upper_range_registers:
            flags |= int(rc.FLAG_UPPER_RANGE_REGISTERS)
        try:
            return rc(self.host, frequency=self.frequency, flags=flags)
        except Exception as err:
            raise connection_failed(self.host, "control", err) from err

    def _check_safe_to_connect(self) -> None:
        """Refuse a stopped or unpowered arm before ur_rtde uploads its script."""
        self._wait_fresh()
        st = self._read_state()
        if st.emergency_stopped:
            raise EmergencyStop(f"UR controller at {self.host} is in an emergency stop or safety "
                                f"fault ({st.describe()}): release the e-stop, then power on and "
                                f"release the brakes")
        if st.protective_stopped:
            raise ProtectiveStop(f"UR controller at {self.host} is in a protective stop "
                                 f"({st.describe()}): clear it on the pendant or with "
                                 f"URArm.recover_protective_stop(), then connect again")
        if not st.running:
            raise ConnectionFailed(f"UR arm at {self.host} is not running ({st.describe()}): "
                                   f"power it on and release the brakes")

    def _set_zero_tcp(self) -> None:
        # Zero TCP: getActualTCPPose becomes the flange (tool0) pose, comparable with our FK.
        if not self._call("setTcp", [0.0] * 6):
            raise ConnectionFailed(f"UR controller at {self.host} refused setTcp (is ur_rtde's "
                                   f"control script running?)")

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

    def _cross_check_kinematics(self) -> None:
        s = self._fresh_sample()
        lin, ang = _pose_error(np.asarray(self.model.flange_pose(s.q), dtype=float), s.tcp_pose)
        self.fk_mismatch = (lin, ang)
        text = f"{lin * 1000:.2f} mm / {np.degrees(ang):.3f} deg"
        name = getattr(self.model, "name", "model")
        if lin > FK_WRONG_MODEL_TOL[0] or ang > FK_WRONG_MODEL_TOL[1]:
            raise ConfigError(
                f"UR controller at {self.host} ({self.controller}) reports a flange pose "
                f"{text} away from the {name} model's FK (limit {FK_WRONG_MODEL_TOL[0] * 1000:g} "
                f"mm): is this arm really a {name}?")
        calibrated = self.kinematics is not None and self.kinematics.calibrated
        tol = FK_CALIBRATED_WARN_TOL if calibrated else FK_WARN_TOL
        if lin > tol[0] or ang > tol[1]:
            if calibrated:
                log.warning("UR controller at %s: its flange pose differs from FK with its own "
                            "calibrated table by %s (allowed %g mm): the table read is not "
                            "this arm's, camera poses will be off", self.host, text,
                            tol[0] * 1000)
            else:
                log.warning("UR controller at %s: flange pose differs from the %s model's FK "
                            "by %s (its calibrated table was not read); camera poses use the "
                            "model", self.host, name, text)

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
                   lambda s: _pose_error(T, s.tcp_pose))

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
            start, watch = self.clock.now(), _DataWatch(self)
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
        _, _, dashboard_client = _import_ur_rtde()
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
        start, watch = self.clock.now(), _DataWatch(self)
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

    def _unlock_via_dashboard(self, dashboard_client, timeout: float) -> None:
        db = dashboard_client.DashboardClient(self.host)
        try:
            db.connect(int(self.connect_timeout * 1000))
        except Exception as err:
            raise connection_failed(self.host, "dashboard", err) from err
        try:
            start = self.clock.now()
            while True:
                try:
                    db.unlockProtectiveStop()
                    break
                except Exception as err:
                    if self.clock.now() - start >= timeout:
                        raise ProtectiveStop(
                            f"could not release the protective stop on UR controller at "
                            f"{self.host} within {timeout:g} s ({_one_line(err)}): UR allows it "
                            f"5 s after the stop; e-Series must be in Remote Control") from err
                    self.clock.sleep(UNLOCK_RETRY_S)
            try:
                db.closeSafetyPopup()
            except Exception as err:  # noqa: BLE001 - cosmetic on the pendant
                log.debug("closeSafetyPopup failed: %s", err)
        finally:
            try:
                db.disconnect()
            except Exception as err:  # noqa: BLE001 - cleanup only
                log.debug("dashboard disconnect failed: %s", err)

    def _resume_control(self, timeout: float) -> None:
        """After an unlock: wait for the stop to clear, re-upload the script, zero the TCP."""
        self._wait_for(lambda st: not st.protective_stopped, timeout,
                       "is still in a protective stop after the unlock")
        # reuploadScript returns False when a script already runs; the wait below decides.
        self._call("reuploadScript", timeout=self.call_timeout + 5.0)
        self._wait_for(lambda st: st.program_running, timeout,
                       "did not restart ur_rtde's control script")
        self._set_zero_tcp()

    def _wait_for(self, ok, timeout: float, failure: str) -> None:
        start = self.clock.now()
        while True:
            st = self._read_state()
            if ok(st):
                return
            if self.clock.now() - start > timeout:
                raise HardwareError(f"UR controller at {self.host} {failure} within {timeout:g} s "
                                    f"({st.describe()})")
            self.clock.sleep(self.poll_interval)

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

    def _rr_get(self, getter: str):
        """A receive-interface getter; ur_rtde's errors become HardwareError."""
        if self._rr is None:
            raise NotConnected(f"{self.name}: not connected; call connect() first")
        try:
            return getattr(self._rr, getter)()
        except ArmstereoError:
            raise
        except Exception as err:
            raise HardwareError(f"UR controller at {self.host}: {getter} failed: "
                                f"{_one_line(err)}") from err

    def _check_link(self, context: str = "") -> None:
        if not self._rr_get("isConnected"):
            raise ConnectionLost(f"lost the RTDE connection to UR controller at {self.host}"
                                 f"{context}")
        if self._ch is not None and not self._call("isConnected"):
            raise ConnectionLost(f"lost the control connection to UR controller at {self.host}"
                                 f"{context}")

    def _read_state(self) -> ControllerState:
        return ControllerState(int(self._rr_get("getSafetyStatusBits")),
                               int(self._rr_get("getSafetyMode")),
                               int(self._rr_get("getRobotMode")),
                               int(self._rr_get("getRuntimeState")))

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

    def _read_sample(self) -> _Sample:
        """Latest joints and TCP pose with the timestamp of the package they came from."""
        for _ in range(3):  # re-read if a new package landed between the getters
            t0 = self._rr_get("getTimestamp")
            q = self._rr_get("getActualQ")
            pose = self._rr_get("getActualTCPPose")
            t1 = self._rr_get("getTimestamp")
            if t0 == t1:
                break
        q, pose = np.asarray(q, dtype=float), np.asarray(pose, dtype=float)
        if q.shape != (6,) or pose.shape != (6,) or not np.all(np.isfinite(np.r_[q, pose])):
            raise HardwareError(f"UR controller at {self.host} sent invalid state: q={q.tolist()}, "
                                f"TCP pose={pose.tolist()}")
        return _Sample(float(t1), q, pose)

    def _fresh_sample(self) -> _Sample:
        self._wait_fresh()
        return self._read_sample()

    def _wait_fresh(self, packages: int = FRESH_PACKAGES) -> None:
        """Block until ``packages`` new RTDE packages arrived after this call began."""
        watch = _DataWatch(self)
        while watch.changes < packages:
            self.clock.sleep(FRESH_POLL_S)
            if not self._rr_get("isConnected"):
                raise ConnectionLost(f"lost the RTDE connection to UR controller at {self.host}")
            watch.check()


class _DataWatch:
    """Counts new RTDE packages (timestamp changes); ConnectionLost when none came for the
    arm's ``data_timeout`` (ur_rtde itself notices only after 2.5 s, and only on EOF or silence
    of its own thread)."""

    def __init__(self, arm: URArm):
        self.arm = arm
        self.last = arm._rr_get("getTimestamp")
        self.since = arm.clock.now()
        self.changes = 0

    def check(self) -> None:
        t, now = self.arm._rr_get("getTimestamp"), self.arm.clock.now()
        if t != self.last:
            self.last, self.since, self.changes = t, now, self.changes + 1
        elif now - self.since > self.arm.data_timeout:
            raise ConnectionLost(f"no new RTDE data from UR controller at {self.arm.host} for "
                                 f"{self.arm.data_timeout:g} s (link lost?)")


def _import_ur_rtde():
    """ur_rtde's three modules, or ConfigError with the install hint."""
    try:
        import dashboard_client
        import rtde_control
        import rtde_receive
    except ImportError as err:
        raise ConfigError(f"the UR backend needs ur_rtde ({err}): pip install ur-rtde") from err
    return rtde_control, rtde_receive, dashboard_client


def _check_host(host) -> str:
    return validate_host(host, "UR host")


def _check_cap(what: str, value: float, cap: float, unit: str) -> None:
    positive(value, what, unit, cap=cap)


def _check_timeout(timeout: float) -> None:
    positive(timeout, "timeout", "s")


def _rigid(T) -> np.ndarray:
    return as_rigid(T, "move_linear target T_base_flange")


def _pose_error(T_target: np.ndarray, ur_pose: np.ndarray) -> tuple[float, float]:
    """(translation m, rotation rad) between a 4x4 pose and a UR pose 6-vector."""
    T = T_from_ur_pose(ur_pose)
    lin = float(np.linalg.norm(T[:3, 3] - T_target[:3, 3]))
    ang = float(np.linalg.norm(matrix_to_rotvec(T_target[:3, :3].T @ T[:3, :3])))
    return lin, ang


def _one_line(err: BaseException) -> str:
    return " ".join(str(err).split()) or type(err).__name__
