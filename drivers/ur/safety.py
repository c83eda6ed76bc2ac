"""What a UR controller's RTDE state words mean, and which :class:`ArmState` they map to.

Codes are the controller's (RTDE ``robot_mode``, ``safety_mode``, ``safety_status_bits``,
``runtime_state``), as listed in UR's RTDE guide and ur_rtde's ``rtde_receive`` docs.
"""

from __future__ import annotations

from dataclasses import dataclass

from armstereo.devices import ArmState

ROBOT_MODES = {
    -1: "NO_CONTROLLER", 0: "DISCONNECTED", 1: "CONFIRM_SAFETY", 2: "BOOTING", 3: "POWER_OFF",
    4: "POWER_ON", 5: "IDLE", 6: "BACKDRIVE", 7: "RUNNING", 8: "UPDATING_FIRMWARE",
}
ROBOT_MODE_RUNNING = 7

SAFETY_MODES = {
    1: "NORMAL", 2: "REDUCED", 3: "PROTECTIVE_STOP", 4: "RECOVERY", 5: "SAFEGUARD_STOP",
    6: "SYSTEM_EMERGENCY_STOP", 7: "ROBOT_EMERGENCY_STOP", 8: "VIOLATION", 9: "FAULT",
    10: "VALIDATE_JOINT_ID", 11: "UNDEFINED_SAFETY_MODE", 12: "AUTOMATIC_MODE_SAFEGUARD_STOP",
    13: "SYSTEM_THREE_POSITION_ENABLING_STOP",
}
SAFETY_MODES_OK = frozenset({1, 2})                     # normal, reduced: the arm may move
SAFETY_MODES_EMERGENCY = frozenset({6, 7, 8, 9})        # e-stops, violation, fault: needs a restart

RUNTIME_STATES = {0: "STOPPING", 1: "STOPPED", 2: "PLAYING", 3: "PAUSING", 4: "PAUSED",
                  5: "RESUMING"}
RUNTIME_PLAYING = 2

# safety_status_bits (bit index -> meaning)
BIT_PROTECTIVE_STOPPED = 2
BIT_RECOVERY_MODE = 3
BIT_SAFEGUARD_STOPPED = 4
BIT_SYSTEM_EMERGENCY_STOPPED = 5
BIT_ROBOT_EMERGENCY_STOPPED = 6
BIT_EMERGENCY_STOPPED = 7
BIT_VIOLATION = 8
BIT_FAULT = 9
_EMERGENCY_BITS = (BIT_SYSTEM_EMERGENCY_STOPPED, BIT_ROBOT_EMERGENCY_STOPPED,
                   BIT_EMERGENCY_STOPPED, BIT_VIOLATION, BIT_FAULT)
_STOP_BITS = (BIT_PROTECTIVE_STOPPED, BIT_RECOVERY_MODE, BIT_SAFEGUARD_STOPPED)


def _name(table: dict[int, str], code: int) -> str:
    return f"{table.get(code, 'UNKNOWN')} ({code})"


@dataclass(frozen=True)
class ControllerState:
    """One reading of the controller's state words (from RTDEReceiveInterface)."""

    safety_status_bits: int
    safety_mode: int
    robot_mode: int
    runtime_state: int

    def _bit(self, bit: int) -> bool:
        return bool((int(self.safety_status_bits) >> bit) & 1)

    @property
    def emergency_stopped(self) -> bool:
        """E-stop (system or robot), safety violation or fault: needs a restart, not an unlock."""
        return (any(self._bit(b) for b in _EMERGENCY_BITS)
                or self.safety_mode in SAFETY_MODES_EMERGENCY)

    @property
    def protective_stopped(self) -> bool:
        """Protective, safeguard or recovery stop: not normal/reduced, and no e-stop."""
        if self.emergency_stopped:
            return False
        return any(self._bit(b) for b in _STOP_BITS) or self.safety_mode not in SAFETY_MODES_OK

    @property
    def running(self) -> bool:
        """The arm is powered with the brakes released (robot mode RUNNING)."""
        return self.robot_mode == ROBOT_MODE_RUNNING

    @property
    def program_running(self) -> bool:
        """A program (ur_rtde's control script, once connected) is playing."""
        return self.runtime_state == RUNTIME_PLAYING

    def arm_state(self) -> ArmState:
        """Our four-state summary. An arm that is not RUNNING (power off, idle, booting) cannot
        move either, so it maps to PROTECTIVE_STOP; :meth:`describe` says which it is."""
        if self.emergency_stopped:
            return ArmState.EMERGENCY_STOP
        if self.protective_stopped or not self.running:
            return ArmState.PROTECTIVE_STOP
        return ArmState.NORMAL

    def describe(self) -> str:
        """One line: robot mode, safety mode, program state (names and codes)."""
        return (f"robot mode {_name(ROBOT_MODES, self.robot_mode)}, "
                f"safety mode {_name(SAFETY_MODES, self.safety_mode)}, "
                f"program {_name(RUNTIME_STATES, self.runtime_state)}")
