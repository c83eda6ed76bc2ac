"""GenTL producers (the vendor's ``.cti`` file) and the harvesters consumer that loads them.

Where the producer comes from: ``--cti`` (a ``.cti`` file, or a folder of them), else the
GenTL convention, the environment variable ``GENICAM_GENTL64_PATH`` (folders separated by
``os.pathsep``; every ``.cti`` in them is loaded). One ``harvesters.Harvester`` per set of
producers is shared in the process: a producer opened twice in one process shows no devices
the second time, and a Harvester's ``update()`` would invalidate the cameras already open.
"""

from __future__ import annotations

import importlib
import logging
import os
import threading
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from armstereo.errors import ConfigError, ConnectionFailed

log = logging.getLogger(__name__)

ENV_VAR = "GENICAM_GENTL64_PATH"
EXTRA_HINT = "pip install 'armstereo[genicam]'"
UPDATE_TIMEOUT_MS = 2000  # how long a producer may take to list its interfaces and devices


def harvesters_core():
    """``harvesters.core``, or ConfigError (exit 2) saying how to install the extra."""
    try:
        module = importlib.import_module("harvesters.core")
    except ImportError as err:
        raise ConfigError(f"the genicam camera needs the optional extra: {EXTRA_HINT} "
                          f"({err})") from None
    if not log.isEnabledFor(logging.DEBUG):
        # harvesters logs every failure with its traceback on its own handler; we report each
        # one in a line of our own
        logging.getLogger("harvesters.core").setLevel(logging.CRITICAL)
    return module


def producer_files(cti: str | None) -> tuple[str, ...]:
    """The ``.cti`` files to load: ``cti`` (a file or a folder) or those in the folders of
    ``GENICAM_GENTL64_PATH``. ConfigError when there is none."""
    if cti is not None:
        path = Path(cti).expanduser()
        if path.is_dir():
            found = sorted(str(p) for p in path.glob("*.cti"))
            if not found:
                raise ConfigError(f"--cti {cti}: the folder holds no .cti file (a GenTL "
                                  "producer from your camera's vendor)")
            return tuple(found)
        if not path.is_file():
            raise ConfigError(f"--cti {cti}: no such GenTL producer file")
        return (str(path.resolve()),)
    folders = [f for f in os.environ.get(ENV_VAR, "").split(os.pathsep) if f.strip()]
    found = sorted({str(p.resolve()) for f in folders if Path(f).is_dir()
                    for p in Path(f).glob("*.cti")})
    if not found:
        where = f"{ENV_VAR}={os.environ[ENV_VAR]!r} holds none" if folders \
            else f"{ENV_VAR} is not set"
        raise ConfigError(f"no GenTL producer: pass --cti PATH to your camera vendor's .cti "
                          f"file, or set {ENV_VAR} to its folder ({where}; docs/cameras.md)")
    return tuple(found)


@dataclass
class _Shared:
    harvester: Any
    users: int


_LOCK = threading.Lock()
_SHARED: dict[tuple[str, ...], _Shared] = {}


def acquire(files: tuple[str, ...]):
    """The process's Harvester for ``files`` (loaded and listing its devices); pair every call
    with :func:`release`. ConfigError when a file is no GenTL producer."""
    core = harvesters_core()
    with _LOCK:
        shared = _SHARED.get(files)
        if shared is None:
            h = core.Harvester()
            try:
                h.timeout_for_update = UPDATE_TIMEOUT_MS
                for f in files:
                    try:
                        h.add_file(f, check_existence=True, check_validity=True)
                    except OSError as err:
                        raise ConfigError(f"{f} is not a loadable GenTL producer: "
                                          f"{_first_line(err)}") from None
                try:
                    h.update()
                except Exception as err:  # noqa: BLE001 - the producer's own exception types
                    raise ConnectionFailed(f"the GenTL producer {', '.join(files)} failed to "
                                           f"list its cameras: {_first_line(err)}") from None
            except BaseException:
                _reset(h)
                raise
            shared = _SHARED[files] = _Shared(h, 0)
        shared.users += 1
        return shared.harvester


def release(files: tuple[str, ...]) -> None:
    """One user of the Harvester for ``files`` is done; the last one unloads it."""
    with _LOCK:
        shared = _SHARED.get(files)
        if shared is None:
            return
        shared.users -= 1
        if shared.users <= 0:
            del _SHARED[files]
            _reset(shared.harvester)


def _reset(h) -> None:
    try:
        h.reset()
    except Exception as err:  # noqa: BLE001 - unloading must not raise
        log.warning("unloading the GenTL producer failed: %s", _first_line(err))


@dataclass(frozen=True)
class DeviceEntry:
    """A camera a producer lists: its index in the list, serial number, vendor, model, the
    GenTL id, the user-defined name and whether another program holds it."""

    index: int
    serial: str
    vendor: str
    model: str
    id: str
    user_name: str
    access: str

    def label(self) -> str:
        return f"{self.index}: serial {self.serial!r} {self.vendor} {self.model}".strip()


_ACCESS = {0: "unknown", 1: "ready", 2: "read-only", 3: "no access", 4: "busy",
           5: "open (read-write)", 6: "open (read-only)"}


def devices(h) -> list[DeviceEntry]:
    """The cameras the Harvester ``h`` lists, in its order."""
    out = []
    for k, info in enumerate(h.device_info_list):
        out.append(DeviceEntry(k, _prop(info, "serial_number"), _prop(info, "vendor"),
                               _prop(info, "model"), _prop(info, "id_"),
                               _prop(info, "user_defined_name"),
                               _ACCESS.get(_access(info), "unknown")))
    return out


def find(entries: list[DeviceEntry], key: str, files: tuple[str, ...]) -> DeviceEntry:
    """The camera ``key`` names: a serial number first, else an index into the list.
    ConnectionFailed (exit 4) listing the cameras found otherwise."""
    for e in entries:
        if e.serial == key or (e.user_name and e.user_name == key):
            return e
    if key.isdigit() and int(key) < len(entries):
        return entries[int(key)]
    seen = "; ".join(e.label() for e in entries) or "none"
    raise ConnectionFailed(f"no GenICam camera with serial or index {key!r} through "
                           f"{', '.join(Path(f).name for f in files)} (cameras found: {seen})")


def _prop(info, name: str) -> str:
    try:
        value = getattr(info, name)
    except Exception:  # noqa: BLE001 - producers leave optional fields unimplemented
        return ""
    return "" if value is None else str(value)


def _access(info) -> int:
    try:
        return int(info.access_status)
    except Exception:  # noqa: BLE001
        return 0


def _first_line(err: BaseException) -> str:
    text = str(err).strip().splitlines()
    return text[0] if text else type(err).__name__
