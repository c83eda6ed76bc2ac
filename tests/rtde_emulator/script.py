"""ur_rtde's control script (``rtde_control.script``), played through its registers.

The emulator never runs URScript: when ur_rtde's program arrives on the script port, this
class takes its place and follows the same register protocol, one loop per controller cycle:

- ``input_int_register_0`` holds the command (0 = none); arguments are in
  ``input_double_register_0..`` and ``input_int_register_1`` (async flag); all indices are
  shifted by the register offset the uploaded script declares (0, or 24 for upper range).
- ``output_int_register_0`` is 1 (ready) after a clear and 2 (done) when a command finished; a
  blocking move or stop delays "done" until the arm is at rest.
- ``output_int_register_2`` is the async progress word: bits 24-30 operation id (incremented when
  an operation starts), bits 16-22 write counter, bit 15 running, bits 0-14 progress.
- Results go to ``output_double_register_0..5`` and ``output_int_register_1``.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from armstereo.transforms import T_from_ur_pose, ur_pose_from_T

if TYPE_CHECKING:
    from .controller import Controller
    from .motion import Motion

READY, DONE = 1, 2
COMMAND_NAMES = {1: "moveJ", 3: "moveL", 29: "setTcp", 31: "triggerProtectiveStop",
                 33: "stopL", 34: "stopJ", 39: "poseTrans", 40: "getTCPOffset",
                 47: "isSteady", 255: "stopScript"}


class ControlScript:
    """One run of ur_rtde's control program on ``controller`` (see the module docstring)."""

    def __init__(self, controller: Controller, register_offset: int):
        self.c = controller
        self.offset = register_offset
        self.executing = False
        self.blocking: Motion | None = None    # what a synchronous move/stop waits for
        self.async_move: Motion | None = None  # the motion of the "move thread"
        self.stop_brake: Motion | None = None  # the motion of the "stop thread" (async stop)
        self.op_id = 0
        self.writes = 0
        self._progress(-1)        # reset_async_progress()
        self._out_int(0, READY)   # signal_ready()

    # ------------------------------------------------------------------------- registers
    def _in_int(self, i: int) -> int:
        return int(self.c.input_value(f"input_int_register_{i + self.offset}"))

    def _in_double(self, i: int, n: int = 1) -> list[float]:
        return [float(self.c.input_value(f"input_double_register_{k + self.offset}"))
                for k in range(i, i + n)]

    def _out_int(self, i: int, value: int) -> None:
        self.c.out_int[i + self.offset] = int(value)

    def _out_pose(self, values) -> None:
        for k, v in enumerate(values):
            self.c.out_double[k + self.offset] = float(v)

    def _progress(self, value: int) -> None:
        """write_async_progress_register(): 0 starts an operation, < 0 ends it."""
        self.writes = 0 if self.writes + 1 > 127 else self.writes + 1
        if value == 0:
            self.op_id = 0 if self.op_id + 1 > 127 else self.op_id + 1
        word = self.writes * 65536 + self.op_id * 16777216
        if value >= 0:
            word += min(value, 32767) + 32768
        self._out_int(2, word)

    # ---------------------------------------------------------------------------- the loop
    def step(self) -> None:
        """One pass of the script's main loop (it runs once per controller cycle)."""
        if self.blocking is not None:
            return
        cmd = self._in_int(0)
        if cmd == 0:
            self.executing = False
            self._out_int(0, READY)
        elif not self.executing:
            self.executing = True
            self._process(cmd)

    def on_motion_end(self, motion: Motion) -> None:
        """The controller finished (or braked to rest) ``motion``."""
        if motion is self.async_move:
            self.async_move = None
            self._progress(-1)
        if motion is self.stop_brake:
            self.stop_brake = None
            self._progress(-1)
        if motion is self.blocking:
            self.blocking = None
            self._out_int(0, DONE)

    def _process(self, cmd: int) -> None:
        name = COMMAND_NAMES.get(cmd)
        if name is None:
            self.c.log("command", name=f"unsupported {cmd}")
            self.c.end_program(f"command {cmd} is not emulated")
            return
        handler = getattr(self, f"_cmd_{name}")
        if handler() is not False:  # False: "done" comes later (blocking) or never
            self._out_int(0, DONE)

    # ---------------------------------------------------------------------------- commands
    def _move(self, kind: str) -> bool:
        target = self._in_double(0, 6)
        speed, acceleration = self._in_double(6, 2)
        asynchronous = self._in_int(1) == 1
        self.c.log("command", name=kind, target=target, speed=speed,
                   acceleration=acceleration, asynchronous=asynchronous)
        self._stop_async_move()
        motion = self.c.start_move(kind, target, speed, acceleration, asynchronous=asynchronous)
        if motion is None:  # the program stopped (unreachable target)
            return False
        if asynchronous:
            self.async_move = motion
            self._progress(0)
            return True
        self.blocking = motion
        return False

    def _cmd_moveJ(self):
        return self._move("moveJ")

    def _cmd_moveL(self):
        return self._move("moveL")

    def _stop_async_move(self) -> None:
        """Kill the move thread (it cannot report its own end then)."""
        if self.async_move is not None:
            self.async_move = None
            self._progress(-1)

    def _stop(self, name: str) -> bool:
        (deceleration,) = self._in_double(0)
        asynchronous = self._in_int(1) == 1
        had_motion = self.c.motion is not None
        self.c.log("command", name=name, deceleration=deceleration, asynchronous=asynchronous,
                   halted_motion=had_motion)
        if self.stop_brake is not None:  # an async stop already runs: restart it
            self.stop_brake = None
            self._progress(-1)
        self._stop_async_move()
        braking = self.c.brake(deceleration)
        if asynchronous:
            self._progress(0)
            self.stop_brake = braking
            if braking is None:
                self._progress(-1)
            return True
        if braking is None:
            return True
        self.blocking = braking
        return False

    def _cmd_stopL(self):
        return self._stop("stopL")

    def _cmd_stopJ(self):
        return self._stop("stopJ")

    def _cmd_setTcp(self):
        pose = self._in_double(0, 6)
        self.c.log("command", name="setTcp", pose=pose)
        self.c.T_flange_tcp = T_from_ur_pose(pose)

    def _cmd_getTCPOffset(self):
        self.c.log("command", name="getTCPOffset")
        self._out_pose(ur_pose_from_T(self.c.T_flange_tcp))

    def _cmd_poseTrans(self):
        p_from, p_from_to = self._in_double(0, 6), self._in_double(6, 6)
        self.c.log("command", name="poseTrans")
        self._out_pose(ur_pose_from_T(T_from_ur_pose(p_from) @ T_from_ur_pose(p_from_to)))

    def _cmd_isSteady(self):
        steady = self.c.is_steady()
        self.c.log("command", name="isSteady", steady=steady)
        self._out_int(1, 1 if steady else 0)

    def _cmd_triggerProtectiveStop(self):
        self.c.log("command", name="triggerProtectiveStop")
        self.c.protective_stop("triggerProtectiveStop")
        return False

    def _cmd_stopScript(self):
        self.c.log("command", name="stopScript")
        self.c.end_program("stopScript")
        return False

