"""Writing a rosbag2 bag (MCAP storage) that ``ros2 bag play`` and ``ros2 bag info`` read.

The bag is a folder: ``metadata.yaml`` (rosbag2's index of topics, counts and times) beside
one ``.mcap`` file (profile ``ros2``, schemas ``ros2msg`` with the distribution's message
definitions, messages CDR, zstd chunks). It is written into a hidden folder next to the
destination and renamed into place when complete, so a failed export leaves no half bag.
"""

from __future__ import annotations

import logging
import os
import shutil
import tempfile
from collections.abc import Mapping
from pathlib import Path

from armstereo.backends import require_extra
from armstereo.errors import ConfigError, OutputError
from armstereo.ros2 import types as R

log = logging.getLogger(__name__)


def check_destination(out: Path, force: bool) -> None:
    """ConfigError unless ``out`` can become a bag: absent, or (with ``force``) an existing
    bag folder (one holding ``metadata.yaml``); other folders and files are never removed."""
    if not str(out).strip():
        raise ConfigError("--out is empty")
    if not out.parent.exists():
        raise ConfigError(f"--out: directory {out.parent} does not exist")
    if not out.exists() and not out.is_symlink():
        return
    if not force:
        raise ConfigError(f"--out {out} exists; pass --force to replace it")
    if not (out.is_dir() and (out / "metadata.yaml").is_file()):
        raise ConfigError(f"--out {out} exists and is not a ROS 2 bag folder (no metadata.yaml);"
                          " it is left alone")


class BagWriter:
    """Writes messages into a new bag; use as a context manager, then :attr:`path` is the bag.

    ``write`` takes a rosbags message object or ready CDR bytes (``raw``). Topics are
    registered on first use with their type and offered QoS. ``custom_data`` (str -> str) goes
    into ``metadata.yaml``'s ``custom_data``.
    """

    def __init__(self, out: str | Path, *, distro: str = R.DEFAULT_DISTRO,
                 custom_data: Mapping[str, str] | None = None) -> None:
        require_extra("ros2")
        from rosbags.rosbag2 import StoragePlugin, Writer
        from rosbags.rosbag2.enums import CompressionFormat, CompressionMode

        self.path = Path(out)
        self.distro = R.distro(distro)
        self.store = R.typestore(distro)
        self.counts: dict[str, int] = {}
        self.types: dict[str, str] = {}
        self._connections: dict[str, object] = {}
        try:
            self._tmp = Path(tempfile.mkdtemp(prefix=f".{self.path.name}.", dir=self.path.parent))
        except OSError as err:
            raise OutputError(f"cannot create the bag beside {self.path}: {err.strerror}"
                              ) from None
        # The folder's name is the storage file's name: rosbags names it <folder>.mcap.
        self._staged = self._tmp / self.path.name
        self._writer = Writer(self._staged, version=self.distro.metadata_version,
                              storage_plugin=StoragePlugin.MCAP)
        # zstd chunks (rosbag2's "storage" compression, what --storage-preset-profile zstd_*
        # does); metadata.yaml then says compression none, as ros2 bag writes it.
        self._writer.set_compression(CompressionMode.STORAGE, CompressionFormat.ZSTD)
        # rosbag2 (Jazzy) reads custom_data as a map whenever the version is >= 6: never empty.
        for key, value in {"writer": "armstereo", **dict(custom_data or {})}.items():
            self._writer.set_custom_data(str(key), str(value))
        self._open = False

    def __enter__(self) -> BagWriter:
        try:
            self._writer.open()
        except Exception as err:  # noqa: BLE001 - rosbags or the file system
            self._discard()
            raise OutputError(f"cannot write bag {self.path}: {err}") from None
        self._open = True
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        if exc_type is not None:
            self._abort()
            return
        try:
            self._writer.close()
            self._open = False
            self._move_into_place()
        except OSError as err:
            self._discard()
            raise OutputError(f"cannot write bag {self.path}: {err.strerror or err}") from None
        finally:
            self._discard()

    def write(self, topic: str, msgtype: str, t_ns: int, msg=None, *, raw: bytes | None = None,
              qos: str = "default") -> None:
        """Append one message at log time ``t_ns`` (integer ns) on ``topic``."""
        conn = self._connections.get(topic)
        if conn is None:
            conn = self._writer.add_connection(topic, msgtype, typestore=self.store,
                                               offered_qos_profiles=R.qos(qos))
            self._connections[topic], self.types[topic] = conn, msgtype
        elif self.types[topic] != msgtype:
            raise OutputError(f"topic {topic} carries {self.types[topic]}, not {msgtype}")
        data = raw if raw is not None else self.store.serialize_cdr(msg, msgtype)
        try:
            self._writer.write(conn, int(t_ns), data)
        except OSError as err:
            raise OutputError(f"writing bag {self.path} failed: {err.strerror or err}") from None
        self.counts[topic] = self.counts.get(topic, 0) + 1

    def _move_into_place(self) -> None:
        # rosbags names itself as the distribution; ros2 bag info shows the one we wrote for.
        meta = self._staged / "metadata.yaml"
        text = meta.read_text()
        meta.write_text(text.replace("\n  ros_distro: rosbags\n",
                                     f"\n  ros_distro: {self.distro.name}\n"))
        if self.path.exists():  # only a bag folder gets here (check_destination)
            shutil.rmtree(self.path)
        os.replace(self._staged, self.path)

    def _abort(self) -> None:
        if self._open:
            try:
                self._writer.abort()
            except Exception as err:  # noqa: BLE001 - the first error is the one to report
                log.debug("aborting the bag writer: %s", err)
        self._discard()

    def _discard(self) -> None:
        shutil.rmtree(self._tmp, ignore_errors=True)
