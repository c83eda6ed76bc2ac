"""Serialised calls into ur_rtde's RTDEControlInterface, each with a deadline.

The control interface is not thread-safe, and its commands wait for the control script's
answer for up to 300 s (ur_rtde's execution timeout) when the link has silently died. Every
call therefore runs on one dedicated thread, one at a time (this is the lock around the
interface), while the caller waits at most ``timeout`` seconds. ur_rtde releases the GIL inside
its methods, so a stuck call blocks only that thread; until it returns, further calls fail at
once with ConnectionLost instead of queueing behind it.
"""

from __future__ import annotations

import queue
import threading
from concurrent.futures import Future
from concurrent.futures import TimeoutError as FutureTimeout
from typing import Any

from armstereo.errors import ArmstereoError, ConnectionLost, HardwareError


class ControlChannel:
    """Runs methods of ``target`` on a daemon worker thread, one at a time, with deadlines.

    Exceptions from ur_rtde (RuntimeError, ValueError, ...) come back as HardwareError naming
    the host and the method; ours (ArmstereoError) pass through unchanged.
    """

    def __init__(self, target: Any, host: str):
        self.target = target
        self.host = host
        self._jobs: queue.SimpleQueue = queue.SimpleQueue()
        self._late: tuple[str, Future] | None = None
        self._closed = False
        self._thread = threading.Thread(target=self._serve, name=f"ur-rtde-control-{host}",
                                        daemon=True)
        self._thread.start()

    @property
    def stuck(self) -> bool:
        """True while a call that missed its deadline has not returned yet."""
        return self._late is not None and not self._late[1].done()

    def call(self, method: str, *args: Any, timeout: float, **kwargs: Any) -> Any:
        """``target.method(*args, **kwargs)`` on the worker; ConnectionLost after ``timeout`` s."""
        if self._closed:
            raise HardwareError(f"UR controller at {self.host}: control interface closed")
        if self.stuck:
            raise ConnectionLost(f"UR controller at {self.host}: an earlier {self._late[0]} call "
                                 f"has not returned (link lost?); {method} not sent")
        job: Future = Future()
        self._jobs.put((job, method, args, kwargs))
        try:
            return job.result(timeout)
        except FutureTimeout:
            self._late = (method, job)
            raise ConnectionLost(f"UR controller at {self.host}: {method} did not return within "
                                 f"{timeout:g} s (link lost?)") from None
        except ArmstereoError:
            raise
        except Exception as err:
            text = " ".join(str(err).split()) or type(err).__name__
            raise HardwareError(f"UR controller at {self.host}: {method} failed: {text}") from err

    def close(self) -> None:
        """Let the worker end after its current call. Idempotent."""
        if not self._closed:
            self._closed = True
            self._jobs.put(None)

    def _serve(self) -> None:
        while True:
            item = self._jobs.get()
            if item is None:
                return
            job, method, args, kwargs = item
            if not job.set_running_or_notify_cancel():
                continue
            try:
                job.set_result(getattr(self.target, method)(*args, **kwargs))
            except BaseException as err:  # noqa: BLE001 - handed to the waiting caller
                job.set_exception(err)
