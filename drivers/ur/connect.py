"""The steps of :class:`drivers.ur.arm.URArm` that set a controller up and bring it back: open
the receive and control interfaces, refuse a stopped arm before the script upload, zero the TCP,
cross-check the controller's flange pose against the model's FK, and release a protective stop
through the dashboard server. A part of ``URArm`` (it uses the arm's link, readings and clock),
kept here so the arm's module holds its life cycle and motion."""

from __future__ import annotations

import logging

import numpy as np

from armstereo.errors import (
    ConfigError,
    ConnectionFailed,
    EmergencyStop,
    HardwareError,
    ProtectiveStop,
)
from armstereo.transforms import T_from_ur_pose, matrix_to_rotvec
from drivers.ur.diagnose import connection_failed
from drivers.ur.readings import one_line

log = logging.getLogger("drivers.ur.arm")  # one logger for the whole arm

# The only RTDE outputs the receive interface subscribes (an explicit list keeps the recipe
# small and names exactly what a controller, or the test emulator, must provide).
RECEIVE_VARIABLES = ("timestamp", "actual_q", "actual_TCP_pose", "robot_mode", "safety_mode",
                     "safety_status_bits", "runtime_state", "target_speed_fraction")

FK_WARN_TOL = (1e-3, 2e-3)          # controller vs model FK: calibration differs, warn
# With the controller's own table, FK reproduces its pose to ~1e-12 m: more than this means the
# table is not this arm's (the per-view check in recordings uses the same 0.1 mm).
FK_CALIBRATED_WARN_TOL = (1e-4, 1e-4)
FK_WRONG_MODEL_TOL = (0.02, 0.05)   # controller vs model FK: not this robot model, refuse
UNLOCK_RETRY_S = 0.5        # dashboard refuses an unlock within 5 s of the stop; retry



class ConnectSteps:
    """Connect and recovery steps of :class:`~drivers.ur.arm.URArm` (see the module doc)."""

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

    def _cross_check_kinematics(self) -> None:
        s = self._fresh_sample()
        lin, ang = pose_error(np.asarray(self.model.flange_pose(s.q), dtype=float), s.tcp_pose)
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
                            f"{self.host} within {timeout:g} s ({one_line(err)}): UR allows it "
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


def import_ur_rtde():
    """ur_rtde's three modules, or ConfigError with the install hint."""
    try:
        import dashboard_client
        import rtde_control
        import rtde_receive
    except ImportError as err:
        raise ConfigError(f"the UR backend needs ur_rtde ({err}): pip install ur-rtde") from err
    return rtde_control, rtde_receive, dashboard_client


def pose_error(T_target: np.ndarray, ur_pose: np.ndarray) -> tuple[float, float]:
    """(translation m, rotation rad) between a 4x4 pose and a UR pose 6-vector."""
    T = T_from_ur_pose(ur_pose)
    lin = float(np.linalg.norm(T[:3, 3] - T_target[:3, 3]))
    ang = float(np.linalg.norm(matrix_to_rotvec(T_target[:3, :3].T @ T[:3, :3])))
    return lin, ang
