"""Serialised calls into ur_rtde's RTDEControlInterface, each with a deadline.

The control interface is not thread-safe, and its commands wait for the control script's
answer for up to 300 s (ur_rtde's execution timeout) when the link has silently died. Every
call therefore runs on the device's own worker thread (:class:`drivers.worker.SerialWorker`),
one at a time, while the caller waits at most ``timeout`` seconds. ur_rtde releases the GIL
inside its methods, so a stuck call blocks only that thread; until it returns, further calls
fail at once with ConnectionLost instead of queueing behind it.
"""

from __future__ import annotations

from typing import Any

from armstereo.errors import ArmstereoError, ConnectionLost, HardwareError, NotConnected
from drivers.worker import DeadlineMissed, SerialWorker


class ControlChannel:
    """Runs methods of ``target`` on a worker thread, one at a time, with deadlines.

    Exceptions from ur_rtde (RuntimeError, ValueError, ...) come back as HardwareError naming
    the host and the method; ours (ArmstereoError) pass through unchanged.
    """

    def __init__(self, target: Any, host: str):
        self.target = target
        self.host = host
        self._worker = SerialWorker(f"ur-rtde-control-{host}")
        self._late_method = ""

    @property
    def stuck(self) -> bool:
        """True while a call that missed its deadline has not returned yet."""
        return self._worker.stuck

    def call(self, method: str, *args: Any, timeout: float, **kwargs: Any) -> Any:
        """``target.method(*args, **kwargs)`` on the worker; ConnectionLost after ``timeout`` s."""
        if self._worker.closed:
            raise NotConnected(f"UR controller at {self.host}: control interface closed")
        if self.stuck:
            raise ConnectionLost(f"UR controller at {self.host}: an earlier {self._late_method} "
                                 f"call has not returned (link lost?); {method} not sent")
        try:
            return self._worker.call(getattr(self.target, method), *args, timeout=timeout,
                                     **kwargs)
        except DeadlineMissed:
            self._late_method = method
            raise ConnectionLost(f"UR controller at {self.host}: {method} did not return within "
                                 f"{timeout:g} s (link lost?)") from None
        except ArmstereoError:
            raise
        except Exception as err:
            text = " ".join(str(err).split()) or type(err).__name__
            raise HardwareError(f"UR controller at {self.host}: {method} failed: {text}") from err

    def close(self) -> None:
        """Let the worker end after its current call. Idempotent."""
        self._worker.close()
