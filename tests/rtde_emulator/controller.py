"""The emulated controller: arm state, safety and robot modes, registers, program life cycle,
motion integration, move faults and the event log the tests read.

Everything here runs under ``Controller.lock``: the clock thread calls :meth:`Controller.step`
once per controller cycle, the connection threads write inputs and issue dashboard and script
port requests.
"""

from __future__ import annotations

import math
import re
import threading

import numpy as np

from armstereo.errors import IKError
from armstereo.robot.arm_model import ArmModel
from armstereo.transforms import T_from_ur_pose, ur_pose_from_T

from .faults import MoveFault, Settings
from .motion import JointPath, LinearPath, Motion
from .protocol import INPUT_TYPES, OUTPUT_TYPES, width
from .script import ControlScript

ROBOT_MODE_RUNNING = 7
SAFETY_NORMAL, SAFETY_PROTECTIVE_STOP = 1, 3
BITS_NORMAL = 1 << 0                              # safety_status_bits: is_normal_mode
BITS_PROTECTIVE = (1 << 2) | (1 << 10)            # is_protective_stopped, stopped_due_to_safety
RUNTIME_STOPPED, RUNTIME_PLAYING = 1, 2
PROGRAM_START_DELAY_S = 0.05   # from the end of a script upload to PLAYING
PROTECTIVE_DECELERATION = 10.0  # m/s^2 or rad/s^2: the safety system stops hard
PROGRAM_STOP_DECELERATION = 4.0  # a stopped program halts the arm
UNLOCK_SETTLE_S = 0.1          # protective stop released this long after the unlock
# ur_rtde injects the value after the comment's line break: "= # int register offset\n24".
_OFFSET = re.compile(r"global reg_offset_int\s*=\s*(?:#[^\n]*\n)?\s*(\d+)")


class Controller:
    """A UR controller's state as the RTDE, dashboard and script-port servers see it."""

    def __init__(self, model: ArmModel, q0: np.ndarray, version: tuple[int, int, int, int],
                 settings: Settings):
        self.lock = threading.RLock()
        self.model = model
        self.version = version
        self.settings = settings
        self.rate_hz = 125.0 if version[0] < 5 else 500.0
        self.time = 0.0
        self.q = np.asarray(q0, dtype=float).copy()
        self.qd = np.zeros(6)
        self.T_flange_tcp = np.eye(4)
        self.safety_mode, self.safety_bits = SAFETY_NORMAL, BITS_NORMAL
        self.runtime_state = RUNTIME_STOPPED
        self.speed_fraction = 1.0
        self.inputs: dict[str, object] = {}
        self.out_int = [0] * 48
        self.out_double = [0.0] * 48
        self.script: ControlScript | None = None
        self.motion: Motion | None = None
        self.moves = 0
        self.faults: list[MoveFault] = []
        self.protective_since: float | None = None
        self._release_at: float | None = None
        self._pending_program: tuple[float, int] | None = None
        self.network_down = False  # set by the disconnect fault; the servers act on it
        self.events: list[dict] = []

    # ------------------------------------------------------------------------- bookkeeping
    def log(self, kind: str, **fields) -> None:
        """Append an event (controller time in s) to the log the tests read."""
        self.events.append({"t": round(self.time, 4), "kind": kind, **fields})

    # ---------------------------------------------------------------------------- the cycle
    def step(self, dt: float) -> None:
        """One controller cycle of ``dt`` s: motion, faults, protective-stop release, script."""
        self.time += dt
        m = self.motion
        if m is not None:
            # The speed slider scales a move's own clock; a stop runs at full rate.
            q = self._advance(m, dt if m.braking else dt * self.speed_fraction)
            self.qd = (q - self.q) / dt
            self.q = q
            self._check_faults(m)
            if m.finished and self.motion is m:
                self.motion = None
                self.log("motion_end", move=m.number, type=m.kind, completed=not m.braking,
                         fraction=round(m.fraction, 4))
                if self.script is not None:
                    self.script.on_motion_end(m)
        else:
            self.qd = np.zeros(6)
        if self._release_at is not None and self.time >= self._release_at:
            self._release_at = self.protective_since = None
            self.safety_mode, self.safety_bits = SAFETY_NORMAL, BITS_NORMAL
            self.log("protective_stop_released")
        if self._pending_program is not None and self.time >= self._pending_program[0]:
            offset = self._pending_program[1]
            self._pending_program = None
            self.runtime_state = RUNTIME_PLAYING
            self.script = ControlScript(self, offset)
            self.log("program_started", register_offset=offset)
        if self.script is not None:
            self.script.step()

    def _advance(self, m: Motion, dt: float) -> np.ndarray:
        try:
            return m.advance(dt)
        except IKError as err:  # a singularity on the way: the controller stops the arm
            self.motion = None
            self.protective_stop(f"moveL path: {err}")
            return self.q

    def _check_faults(self, m: Motion) -> None:
        for f in self.faults:
            if f.fired or f.move != m.number or m.fraction < f.at:
                continue
            f.fired = True
            self.log("fault", fault=f.kind, move=m.number, fraction=round(m.fraction, 4))
            if f.kind == "protective_stop":
                self.protective_stop("injected fault")
            elif f.kind == "stall":
                self.speed_fraction = 0.0
            elif f.kind == "disconnect":
                self.network_down = True

    # ------------------------------------------------------------------------------ motion
    def start_move(self, kind: str, target: list[float], speed: float, acceleration: float,
                   *, asynchronous: bool) -> Motion | None:
        """Begin moveJ (joints) or moveL (TCP pose); None (program error) if unreachable."""
        self.moves += 1
        try:
            if kind == "moveJ":
                path = JointPath(self.q, np.asarray(target, dtype=float))
            else:
                path = LinearPath(self.model, self.q, self.T_flange_tcp, T_from_ur_pose(target))
        except IKError as err:
            self.end_program(f"{kind} target unreachable: {err}")
            return None
        self.motion = Motion(kind, path, speed, acceleration, asynchronous=asynchronous,
                             number=self.moves)
        return self.motion

    def brake(self, deceleration: float) -> Motion | None:
        """Decelerate the current move to rest; the braking motion, or None if at rest."""
        m = self.motion
        if m is None:
            return None
        m.brake(deceleration if self.speed_fraction > 0 else math.inf)  # held still: at rest
        return m

    def is_steady(self) -> bool:
        return self.motion is None

    def tcp_pose(self) -> list[float]:
        return ur_pose_from_T(self.model.flange_pose(self.q) @ self.T_flange_tcp).tolist()

    # ----------------------------------------------------------------- safety and programs
    def protective_stop(self, reason: str) -> None:
        """Safety stop: halt the arm, stop the program, refuse moves until unlocked."""
        self.safety_mode, self.safety_bits = SAFETY_PROTECTIVE_STOP, BITS_PROTECTIVE
        self.protective_since = self.time
        self.brake(PROTECTIVE_DECELERATION)
        self.log("protective_stop", reason=reason)
        self.end_program("protective stop")

    def unlock_protective_stop(self) -> bool:
        """Dashboard unlock; False while the stop is younger than ``unlock_delay_s``."""
        if self.protective_since is None:
            return True
        if self.time - self.protective_since < self.settings.unlock_delay_s:
            return False
        self._release_at = self.time + UNLOCK_SETTLE_S
        return True

    def end_program(self, reason: str) -> None:
        """The running program stops (stopScript, dashboard stop, safety, error)."""
        self._pending_program = None
        if self.script is None and self.runtime_state == RUNTIME_STOPPED:
            return
        self.script = None
        self.runtime_state = RUNTIME_STOPPED
        if self.motion is not None and not self.motion.braking:
            self.brake(PROGRAM_STOP_DECELERATION)
        self.log("program_stopped", reason=reason)

    def upload_program(self, text: str) -> None:
        """A ``def ...: ... end`` program arrived on the script port: replace the running one."""
        match = _OFFSET.search(text)
        offset = int(match.group(1)) if match else 0
        self.log("script_upload", chars=len(text), register_offset=offset)
        if self.robot_mode != ROBOT_MODE_RUNNING or self.safety_mode != SAFETY_NORMAL:
            self.log("program_refused", reason="arm not running or in a safety stop")
            return
        self.end_program("replaced by an upload")
        self._pending_program = (self.time + PROGRAM_START_DELAY_S, offset)

    @property
    def robot_mode(self) -> int:
        """RTDE robot mode; a test sets it (``Settings.robot_mode``) like a pendant would."""
        return self.settings.robot_mode

    # ---------------------------------------------------------------------------- registers
    def write_inputs(self, values: dict[str, object]) -> None:
        self.inputs.update(values)

    def input_value(self, name: str):
        if name in self.inputs:
            return self.inputs[name]
        return 0.0 if INPUT_TYPES.get(name) == "DOUBLE" else 0

    def output_values(self, names: set[str]) -> dict[str, object]:
        """Current value of each named RTDE output."""
        pose = self.tcp_pose() if names & {"actual_TCP_pose", "target_TCP_pose"} else None
        status = (1 if self.robot_mode >= 4 else 0) | (
            2 if self.runtime_state == RUNTIME_PLAYING else 0)
        known = {
            "timestamp": self.time, "actual_q": self.q.tolist(), "target_q": self.q.tolist(),
            "actual_qd": self.qd.tolist(), "target_qd": self.qd.tolist(),
            "actual_TCP_pose": pose, "target_TCP_pose": pose,
            "robot_mode": self.robot_mode, "safety_mode": self.safety_mode,
            "safety_status_bits": self.safety_bits, "runtime_state": self.runtime_state,
            "robot_status_bits": status, "target_speed_fraction": self.speed_fraction,
            "speed_scaling": self.speed_fraction,
        }
        out = {}
        for name in names:
            if name in known:
                out[name] = known[name]
            elif name.startswith("output_int_register_"):
                out[name] = self.out_int[int(name.rsplit("_", 1)[1])]
            elif name.startswith("output_double_register_"):
                out[name] = self.out_double[int(name.rsplit("_", 1)[1])]
            else:  # served, not modelled: zeros of the right shape
                n = width(OUTPUT_TYPES[name])
                out[name] = [0] * n if n > 1 else 0
        return out

    def state(self) -> dict:
        """Snapshot for the control channel."""
        return {
            "time": self.time, "q": self.q.tolist(), "tcp_pose": self.tcp_pose(),
            "tcp_offset": ur_pose_from_T(self.T_flange_tcp).tolist(),
            "robot_mode": self.robot_mode, "safety_mode": self.safety_mode,
            "runtime_state": self.runtime_state, "speed_fraction": self.speed_fraction,
            "moving": self.motion is not None, "moves": self.moves,
        }
