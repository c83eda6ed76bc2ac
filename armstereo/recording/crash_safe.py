"""What keeps a recording readable whatever happens to its writer: the file is locked for one
writer before it is emptied, and SIGINT/SIGTERM are held back while a write is under way (see
:mod:`~armstereo.recording.writer` for the flush after every call)."""

from __future__ import annotations

import contextlib
import os
import signal
import threading
from collections.abc import Iterator
from pathlib import Path

try:  # POSIX: an advisory lock keeps two writers off one file
    import fcntl
except ImportError:  # pragma: no cover - Windows: no lock, the last writer wins
    fcntl = None

from armstereo.errors import ConfigError, RecordingError


def open_exclusive(path: Path):
    """``path`` opened for writing, emptied, and locked for this process alone.

    The lock is taken before the file is emptied, so a second writer of the same file (two
    captures with ``--force``) fails at once and the first one's views survive. The lock goes
    with the file descriptor (closed by :meth:`RecordingWriter.close` or process death).
    """
    try:
        fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o666)
    except OSError as err:
        raise RecordingError(f"cannot create recording {path}: {err.strerror}") from None
    try:
        if fcntl is not None:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        os.close(fd)
        raise ConfigError(f"{path} is being written by another process; choose another "
                          "--out or wait for it to finish") from None
    try:
        os.ftruncate(fd, 0)
        return os.fdopen(fd, "wb")
    except OSError as err:
        os.close(fd)
        raise RecordingError(f"cannot create recording {path}: {err.strerror}") from None


@contextlib.contextmanager
def signals_deferred() -> Iterator[None]:
    """Hold SIGINT/SIGTERM during a write and deliver them after it (main thread only)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    pending: list[int] = []
    previous: dict[int, object] = {}

    def hold(signum, frame):
        pending.append(signum)

    try:
        for sig in (signal.SIGINT, signal.SIGTERM):
            handler = signal.getsignal(sig)
            if handler is not None:  # None: installed outside Python, cannot be restored
                previous[sig] = signal.signal(sig, hold)
        yield
    finally:
        # SIGINT last, so a Ctrl-C arriving meanwhile cannot leave SIGTERM held for good.
        for sig, handler in reversed(previous.items()):
            signal.signal(sig, handler)
        for sig in dict.fromkeys(pending):
            signal.raise_signal(sig)  # now handled as if it had arrived just after the write
