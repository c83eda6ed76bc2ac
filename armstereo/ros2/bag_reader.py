"""Reading a ROS 2 bag (folder with metadata.yaml, or a bare ``.mcap`` / ``.db3`` file) through
rosbags, so that nothing in the file can raise anything but :class:`RecordingError` or
:class:`ConfigError`.

Messages are decoded with the standard definitions (Humble's store; identical in Jazzy for the
types read here). A bag that stores its own definition of a type (rosbag2 does since Iron, and
in MCAP storage always) is checked against it by RIHS01 type hash, so a bag whose
``sensor_msgs/msg/Image`` is not the standard one is refused instead of misread. A message
that cannot be decoded is skipped and counted; a file that cannot be read on is read up to
there, with a warning.
"""

from __future__ import annotations

import logging
from collections import Counter
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path

from armstereo.backends import require_extra
from armstereo.errors import ConfigError, RecordingError
from armstereo.ros2 import types as R

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class TopicInfo:
    """A topic of the bag: its message type and message count (from the bag's index)."""

    name: str
    msgtype: str
    count: int


class BagReader:
    """An opened bag; use as a context manager. ``topics``: name -> TopicInfo;
    ``custom_data``: metadata.yaml's custom_data (empty for a bare storage file);
    ``warnings``: one line per problem met while reading."""

    def __init__(self, path: str | Path) -> None:
        require_extra("ros2")
        from rosbags.rosbag2 import Reader

        self.path = Path(path)
        self.store = R.typestore(R.DEFAULT_DISTRO)
        self.warnings: list[str] = []
        self.stopped: str | None = None  # why reading ended early, if it did
        self._bad: Counter[str] = Counter()
        self._checked: dict[str, str | None] = {}
        try:
            self._reader = Reader(self.path)
            self._reader.open()
            conns = list(self._reader.connections)
            metadata = getattr(self._reader.storage, "metadata", None)
            custom = getattr(metadata, "custom", None) or {}
            self.custom_data = {str(k): str(v) for k, v in dict(custom).items()}
        except Exception as err:  # noqa: BLE001 - hostile files make rosbags raise anything
            raise RecordingError(f"{self.path} is not a readable ROS 2 bag "
                                 f"({describe(err)})") from None
        self._connections = conns
        self.topics: dict[str, TopicInfo] = {}
        for c in conns:
            known = self.topics.get(c.topic)
            if known is not None and known.msgtype != c.msgtype:
                self.warnings.append(f"topic {c.topic} carries two types ({known.msgtype}, "
                                     f"{c.msgtype}); only {known.msgtype} is read")
                continue
            n = (known.count if known else 0) + int(c.msgcount or 0)
            self.topics[c.topic] = TopicInfo(c.topic, c.msgtype, n)

    def __enter__(self) -> BagReader:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def close(self) -> None:
        try:
            self._reader.close()
        except Exception as err:  # noqa: BLE001 - closing must not hide the real error
            log.debug("closing %s: %s", self.path, err)

    def topics_of_type(self, msgtypes: Sequence[str]) -> list[str]:
        return sorted(t.name for t in self.topics.values() if t.msgtype in msgtypes)

    def require(self, topic: str, msgtypes: Sequence[str], what: str) -> str:
        """The type of ``topic``; ConfigError (naming the bag's candidates) when it is absent,
        RecordingError when it carries another type or a non-standard definition."""
        info = self.topics.get(topic)
        if info is None:
            others = self.topics_of_type(msgtypes)
            hint = (f"its {what} topics: {', '.join(others)}" if others
                    else f"it has no {what} topic ({' or '.join(msgtypes)})")
            raise ConfigError(f"{self.path.name} has no topic {topic}; {hint}")
        if info.msgtype not in msgtypes:
            raise RecordingError(f"{topic} in {self.path.name} carries {info.msgtype}, not "
                                 f"{' or '.join(msgtypes)} ({what})")
        problem = self._definition_problem(topic, info.msgtype)
        if problem:
            raise RecordingError(f"{topic} in {self.path.name}: {problem}")
        return info.msgtype

    def _definition_problem(self, topic: str, msgtype: str) -> str | None:
        if topic in self._checked:
            return self._checked[topic]
        problem = None
        for c in self._connections:
            if c.topic != topic or c.msgtype != msgtype:
                continue
            try:
                same = _same_definition(c.msgdef, msgtype, self.store)
            except Exception as err:  # noqa: BLE001 - a hostile definition text
                problem = f"its definition of {msgtype} cannot be parsed ({describe(err)})"
                break
            if same is False:
                problem = (f"its definition of {msgtype} differs from the one ROS 2 Humble "
                           "and Jazzy ship (armstereo reads only the standard message)")
                break
        self._checked[topic] = problem
        return problem

    def messages(self, topics: Sequence[str]) -> Iterator[tuple[str, int, object]]:
        """(topic, log time ns, decoded message) of ``topics`` in log-time order; messages that
        cannot be decoded are skipped (counted in :meth:`problems`)."""
        wanted = [c for c in self._connections
                  if c.topic in topics and c.msgtype == self.topics[c.topic].msgtype]
        if not wanted:
            return
        it = iter(self._reader.messages(connections=wanted))
        while True:
            try:
                conn, t_ns, raw = next(it)
            except StopIteration:
                return
            except Exception as err:  # noqa: BLE001 - a damaged chunk, index or database
                self.stopped = f"reading stopped early ({describe(err)})"
                return
            try:
                msg = self.store.deserialize_cdr(raw, conn.msgtype)
            except Exception:  # noqa: BLE001 - hostile payloads make the decoder raise anything
                self._bad[conn.topic] += 1
                continue
            yield conn.topic, int(t_ns), msg

    def bad_message(self, topic: str) -> None:
        """Count a decoded message whose content is unusable (e.g. NaN pose, odd sizes)."""
        self._bad[topic] += 1

    def problems(self) -> list[str]:
        out = list(self.warnings)
        out += [f"{n} message(s) on {t} could not be decoded or used; skipped"
                for t, n in sorted(self._bad.items())]
        if self.stopped:
            out.append(f"{self.path.name}: {self.stopped}; what came before was used")
        return out


def describe(err: BaseException) -> str:
    """One short line naming an exception."""
    text = str(err).strip().splitlines()[0][:160] if str(err).strip() else ""
    return f"{type(err).__name__}: {text}" if text else type(err).__name__


def _same_definition(msgdef, msgtype: str, store) -> bool | None:
    """Whether a connection's stored definition is ``store``'s (by RIHS01 hash); None when the
    bag stores none (sqlite3 bags before Iron)."""
    from rosbags.interfaces import MessageDefinitionFormat
    from rosbags.typesys import Stores, get_types_from_idl, get_types_from_msg, get_typestore

    if msgdef is None or msgdef.format == MessageDefinitionFormat.NONE or not msgdef.data:
        return None
    if msgdef.format == MessageDefinitionFormat.IDL:
        types = get_types_from_idl(msgdef.data)
    else:
        types = get_types_from_msg(msgdef.data, msgtype)
    fresh = get_typestore(Stores.EMPTY)
    fresh.register(types)
    return fresh.hash_rihs01(msgtype) == store.hash_rihs01(msgtype)
