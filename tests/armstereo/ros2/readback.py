"""A second, independent ROS 2 reader for the bags armstereo writes: the mcap library with
mcap-ros2-support's CDR decoder and its own parser of message definitions (rosidl's, vendored),
and a tf lookup written here. Nothing of rosbags (the writer) is used to read."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from mcap.reader import make_reader
from mcap_ros2._vendor.rosidl_adapter.parser import parse_message_string
from mcap_ros2.decoder import DecoderFactory

SEPARATOR = "=" * 80 + "\n"


@dataclass
class Bag:
    """A bag read back: profile, schemas {name: (encoding, text)}, channels {topic: (schema,
    message encoding, metadata)}, messages {topic: [(log_time, decoded)]}, metadata.yaml."""

    profile: str
    schemas: dict[str, tuple[str, str]]
    channels: dict[str, tuple[str, str, dict]]
    messages: dict[str, list] = field(default_factory=dict)
    metadata: dict = field(default_factory=dict)
    storage: Path | None = None

    def decoded(self, topic: str) -> list:
        return [m for _, m in self.messages.get(topic, [])]


def read_bag(folder: Path) -> Bag:
    """Every message of the bag folder decoded (a failure to decode one raises)."""
    meta = load_yaml(folder / "metadata.yaml")["rosbag2_bagfile_information"]
    files = meta["relative_file_paths"]
    assert len(files) == 1
    storage = folder / files[0]
    with open(storage, "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        summary = reader.get_summary()
        bag = Bag(reader.get_header().profile,
                  {s.name: (s.encoding, s.data.decode()) for s in summary.schemas.values()},
                  {c.topic: (summary.schemas[c.schema_id].name, c.message_encoding,
                             dict(c.metadata)) for c in summary.channels.values()},
                  metadata=meta, storage=storage)
        for _schema, channel, message, decoded in reader.iter_decoded_messages(
                log_time_order=True):
            bag.messages.setdefault(channel.topic, []).append((message.log_time, decoded))
    return bag


def load_yaml(path: Path):
    """YAML with ruamel's safe loader (the YAML 1.2 parser rosbags also depends on)."""
    from ruamel.yaml import YAML

    return YAML(typ="safe").load(path.read_text())


def stamp_ns(stamp) -> int:
    return stamp.sec * 1_000_000_000 + stamp.nanosec


def transform_matrix(tf) -> np.ndarray:
    t, q = tf.transform.translation, tf.transform.rotation
    x, y, z, w = q.x, q.y, q.z, q.w
    T = np.eye(4)
    T[:3, :3] = [[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                 [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                 [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]]
    T[:3, 3] = (t.x, t.y, t.z)
    return T


def lookup_at(bag: Bag, target: str, source: str, t_ns: int) -> np.ndarray | None:
    """T_target_source from /tf_static and the /tf transforms stamped exactly ``t_ns`` (what
    a tf2 buffer gives at that stamp); None when the chain is incomplete there."""
    parent: dict[str, tuple[str, np.ndarray]] = {}
    for msg in bag.decoded("/tf_static"):
        for tf in msg.transforms:
            parent[tf.child_frame_id] = (tf.header.frame_id, transform_matrix(tf))
    for msg in bag.decoded("/tf"):
        for tf in msg.transforms:
            if stamp_ns(tf.header.stamp) == t_ns:
                parent[tf.child_frame_id] = (tf.header.frame_id, transform_matrix(tf))

    def to_root(frame: str) -> tuple[str, np.ndarray]:
        T = np.eye(4)
        while frame in parent:
            p, T_pc = parent[frame]
            T, frame = T_pc @ T, p
        return frame, T

    (ra, Ta), (rb, Tb) = to_root(target), to_root(source)
    return None if ra != rb else np.linalg.inv(Ta) @ Tb


def schema_types(text: str, root: str) -> dict[str, list[str]]:
    """Every type of a ros2msg schema text (root and its dependencies) parsed by rosidl's
    parser: ``pkg/msg/Name`` -> lines ``type name`` for fields and ``type NAME=value``."""
    out = {}
    for k, section in enumerate(text.split(SEPARATOR)):
        if k == 0:
            name, body = root, section
        else:
            first, _, body = section.partition("\n")
            assert first.startswith("MSG: "), first
            pkg, short = first[5:].strip().split("/")[0], first[5:].strip().split("/")[-1]
            name = f"{pkg}/msg/{short}"
        pkg, _, short = name.split("/")
        spec = parse_message_string(pkg, short, body)
        out[name] = ([f"{c.type} {c.name}={c.value}" for c in spec.constants]
                     + [f"{_plain(str(f.type))} {f.name}" for f in spec.fields])
    return out


def _plain(type_string: str) -> str:
    return type_string.replace("/msg/", "/")


def store_types(store, root: str) -> dict[str, list[str]]:
    """The same lines from a rosbags type store (the distribution's definitions), for
    ``root`` and every type it uses."""
    from rosbags.interfaces import Nodetype

    out: dict[str, list[str]] = {}

    def spec(node) -> str:
        kind, detail = node
        if kind == Nodetype.BASE:
            base, bound = detail
            return f"{base}<={bound}" if bound else base
        if kind == Nodetype.NAME:
            visit(detail)
            return _plain(detail)
        inner, count = detail
        text = spec(inner)
        if kind == Nodetype.ARRAY:
            return f"{text}[{count}]"
        return f"{text}[<={count}]" if count else f"{text}[]"

    def visit(name: str) -> None:
        if name in out:
            return
        out[name] = []
        consts, fields = store.fielddefs[name]
        out[name] = ([f"{t} {n}={_const(v)}" for n, t, v in consts]
                     + [f"{spec(node)} {n}" for n, node in fields])

    visit(root)
    return out


def _const(v) -> str:
    return str(v).lower() if isinstance(v, bool) else str(v)
