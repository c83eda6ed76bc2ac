"""Fault switches of the emulated controller, set at start or through the control channel.

Move faults strike during the ``move``-th motion command (moveJ/moveL, counted from 1 since
the emulator started) once ``at`` of its path is covered:

- ``protective_stop``: the safety system stops the arm (safety mode PROTECTIVE_STOP, the
  program stops, as a collision would).
- ``disconnect``: the controller drops every connection and stops answering on its ports (a
  cable pulled, a controller rebooting); the arm finishes the move nobody watches.
- ``stall``: the speed slider drops to 0 %: the program runs on, the arm holds still, the move
  never finishes until someone stops it.

Settings: ``start_delay_s`` (a controller slow to start streaming: RTDE data begins this long
after the client's start request), ``unlock_delay_s`` (the dashboard refuses to unlock a
protective stop this soon after it; UR's rule is 5 s), ``remote_control`` (what ``is in remote
control`` answers on e-Series), ``robot_mode`` (7 RUNNING; e.g. 3 POWER_OFF or 5 IDLE, brakes
on: no program starts), ``primary_fault`` (how the primary stream misbehaves for new
connections; see ``primary_server``).
"""

from __future__ import annotations

from dataclasses import dataclass

MOVE_FAULTS = ("protective_stop", "disconnect", "stall")


@dataclass
class MoveFault:
    """One armed move fault (see the module docstring)."""

    kind: str
    move: int
    at: float = 0.5
    fired: bool = False

    def __post_init__(self) -> None:
        if self.kind not in MOVE_FAULTS:
            raise ValueError(f"unknown fault {self.kind!r}; known: {', '.join(MOVE_FAULTS)}")
        if self.move < 1 or not (0.0 <= self.at <= 1.0):
            raise ValueError(f"fault {self.kind}: move must be >= 1 and at in [0, 1], got "
                             f"move={self.move}, at={self.at}")


@dataclass
class Settings:
    """Controller behaviour a test may change (see the module docstring)."""

    start_delay_s: float = 0.0
    unlock_delay_s: float = 5.0
    remote_control: bool = True
    robot_mode: int = 7
    primary_fault: str = ""

    def update(self, values: dict) -> None:
        """Set the named fields; ValueError for an unknown one."""
        for key, value in values.items():
            if key not in self.__dataclass_fields__:
                raise ValueError(f"unknown setting {key!r}")
            setattr(self, key, type(getattr(self, key))(value))
