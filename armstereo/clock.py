"""Clocks shared by an arm and a camera so timestamps agree.

The mock backends run on :class:`SimClock` by default (sleeps return at once and advance
simulated time, so tests stay fast); real hardware uses :class:`RealClock`.
"""

from __future__ import annotations

import time
from abc import ABC, abstractmethod


class Clock(ABC):
    """Monotonic time source in integer nanoseconds."""

    @abstractmethod
    def now_ns(self) -> int:
        """Current time, integer nanoseconds."""

    @abstractmethod
    def sleep(self, seconds: float) -> None:
        """Wait ``seconds`` (simulated clocks just advance)."""

    def now(self) -> float:
        """Current time in seconds."""
        return self.now_ns() * 1e-9


class RealClock(Clock):
    """Wall-clock time (``time.time_ns``), so recordings carry real capture times."""

    def now_ns(self) -> int:
        return time.time_ns()

    def sleep(self, seconds: float) -> None:
        if seconds > 0:
            time.sleep(seconds)


class SimClock(Clock):
    """Simulated time: ``sleep`` advances the clock instantly. Starts at ``start_ns``."""

    def __init__(self, start_ns: int = 1_700_000_000_000_000_000):
        self._t = int(start_ns)

    def now_ns(self) -> int:
        return self._t

    def sleep(self, seconds: float) -> None:
        if seconds > 0:
            self._t += int(round(seconds * 1e9))

    def advance_ns(self, dt_ns: int) -> None:
        self._t += int(dt_ns)
