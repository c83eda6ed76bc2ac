"""One worker thread per device, so a blocking vendor call can never block the caller.

Vendor calls (OpenCV's VideoCapture, ur_rtde's control interface) are not thread-safe and can
block for seconds, or minutes on a dead link. Each device therefore runs them on its own daemon
thread, one at a time (this is also the lock around the device), while the caller waits at most
a deadline. A call that misses its deadline keeps the thread busy until it returns; ``stuck``
says so, and callers refuse further calls instead of queueing them behind it.
"""

from __future__ import annotations

import queue
import threading
from collections.abc import Callable
from concurrent.futures import Future
from concurrent.futures import TimeoutError as FutureTimeout
from typing import Any


class DeadlineMissed(TimeoutError):
    """A call did not return within its deadline (it may still be running on the worker)."""


class SerialWorker:
    """A daemon thread named ``name`` that runs submitted callables in order."""

    def __init__(self, name: str):
        self.name = name
        self._jobs: queue.SimpleQueue = queue.SimpleQueue()
        self._late: Future | None = None
        self._closed = False
        threading.Thread(target=self._serve, name=name, daemon=True).start()

    @property
    def closed(self) -> bool:
        return self._closed

    @property
    def stuck(self) -> bool:
        """True while a call that missed its deadline has not returned yet."""
        return self._late is not None and not self._late.done()

    def submit(self, fn: Callable[..., Any], *args: Any, **kwargs: Any) -> Future:
        """Queue ``fn(*args, **kwargs)``; its Future carries the result or the exception."""
        job: Future = Future()
        self._jobs.put((job, fn, args, kwargs))
        return job

    def call(self, fn: Callable[..., Any], *args: Any, timeout: float, **kwargs: Any) -> Any:
        """Run ``fn`` on the worker and wait up to ``timeout`` seconds for its result.

        Raises what ``fn`` raised, or :class:`DeadlineMissed`; a call that had not started by
        then is cancelled (it never runs late)."""
        job = self.submit(fn, *args, **kwargs)
        try:
            return job.result(timeout)
        except FutureTimeout:
            if not job.cancel():
                self._late = job
            raise DeadlineMissed(f"{self.name}: no answer within {timeout:g} s") from None

    def close(self) -> None:
        """Let the thread end after its current call. Idempotent."""
        if not self._closed:
            self._closed = True
            self._jobs.put(None)

    def _serve(self) -> None:
        while (item := self._jobs.get()) is not None:
            job, fn, args, kwargs = item
            if job.set_running_or_notify_cancel():
                try:
                    job.set_result(fn(*args, **kwargs))
                except BaseException as err:  # noqa: BLE001 - handed to the waiting caller
                    job.set_exception(err)
