"""Writing files so that a crash, a full disk or a read-only folder never leaves half a file.

Every product armstereo writes (PLY, PNG, PFM, JSON) goes through :func:`write_bytes_atomic`:
the bytes go to a temporary file in the same folder, which is renamed over the target only when
complete. A failure removes the temporary file and raises :class:`armstereo.errors.OutputError`
naming the path; what was written before stays.
"""

from __future__ import annotations

import contextlib
import os
import tempfile
from collections.abc import Iterator
from pathlib import Path

from armstereo.errors import OutputError


def _umask() -> int:
    """The process umask (reading it means setting it, so set it straight back)."""
    mask = os.umask(0)
    os.umask(mask)
    return mask


def write_bytes_atomic(path: str | Path, data: bytes) -> Path:
    """Write ``data`` to ``path`` through a temporary file in the same folder and a rename.

    Raises OutputError naming ``path`` and the reason (no space left, read-only file system,
    permission denied, no such folder).
    """
    path = Path(path)
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    except OSError as err:
        raise OutputError(f"cannot write {path}: {err.strerror or err}") from None
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
        # mkstemp makes the file private (0600); give it the mode a plain open() would have
        os.chmod(tmp, 0o666 & ~_umask())
        os.replace(tmp, path)
    except OSError as err:
        Path(tmp).unlink(missing_ok=True)
        raise OutputError(f"cannot write {path}: {err.strerror or err}") from None
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path


def write_text_atomic(path: str | Path, text: str) -> Path:
    """:func:`write_bytes_atomic` for UTF-8 text (reports, JSON)."""
    return write_bytes_atomic(path, text.encode("utf-8"))


@contextlib.contextmanager
def output_folder(path: str | Path) -> Iterator[Path]:
    """Make the folder ``path`` (and its parents) for a run's outputs; if the run fails and the
    folder was made here and is still empty, remove it again, so a failed run leaves nothing.

    Raises OutputError naming the folder when it cannot be made (read-only, no permission).
    """
    path = Path(path)
    made = [p for p in (path, *path.parents) if not p.exists()]
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise OutputError(f"cannot create output folder {path}: {err.strerror or err}") from None
    try:
        yield path
    except BaseException:
        for folder in made:  # innermost first
            with contextlib.suppress(OSError):  # not empty, or gone: leave it
                folder.rmdir()
        raise
