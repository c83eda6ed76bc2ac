"""Read armstereo recordings, including unfinished, truncated and damaged ones.

A finished file is read through its index (summary section): each chunk is read on its own, so
a damaged chunk loses only its own messages. A file without a usable index (the capture was
killed, the copy was cut short) is read by streaming from the start, stopping at the first record
that cannot be read. Either way :attr:`Recording.lost` says what could not be read and
:attr:`Recording.warnings` lists every problem in one line each. Nothing the file contains can
make the reader raise anything but :class:`RecordingError`.
"""

from __future__ import annotations

import io
import json
import logging
import struct
import zlib
from collections import Counter
from collections.abc import Iterator
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path

import cv2
import numpy as np
from foxglove_schemas_protobuf.CameraCalibration_pb2 import CameraCalibration
from foxglove_schemas_protobuf.CompressedImage_pb2 import CompressedImage
from foxglove_schemas_protobuf.FrameTransforms_pb2 import FrameTransforms
from foxglove_schemas_protobuf.PackedElementField_pb2 import PackedElementField
from foxglove_schemas_protobuf.PointCloud_pb2 import PointCloud
from foxglove_schemas_protobuf.RawImage_pb2 import RawImage
from mcap.data_stream import ReadDataStream
from mcap.opcode import Opcode
from mcap.records import (
    Channel,
    Chunk,
    ChunkIndex,
    DataEnd,
    Footer,
    Header,
    Message,
    MessageIndex,
    Metadata,
    MetadataIndex,
    Schema,
    Statistics,
    SummaryOffset,
)
from mcap.stream_reader import breakup_chunk

from armstereo.camera_model import Intrinsics
from armstereo.errors import RecordingError
from armstereo.recording import schemas as S
from armstereo.transforms import make_T, matrix_from_quaternion_xyzw

log = logging.getLogger(__name__)

MAGIC = b"\x89MCAP0\r\n"
RECORD_HEADER = 9  # opcode (1) + length (8)
FOOTER_RECORD = RECORD_HEADER + 20
MAX_CHUNK_BYTES = 1 << 30  # larger "uncompressed sizes" are taken as damage, not allocated
MAX_IMAGE_PIXELS = 1 << 26  # 64 Mpx: refuse to decode absurd image headers
BASELINE_TOLERANCE_M = 1e-4  # event vs poses: larger differences are reported

_PARSERS = {
    Opcode.HEADER: Header.read, Opcode.FOOTER: Footer.read, Opcode.SCHEMA: Schema.read,
    Opcode.CHANNEL: Channel.read, Opcode.CHUNK: Chunk.read, Opcode.MESSAGE_INDEX:
    MessageIndex.read, Opcode.CHUNK_INDEX: ChunkIndex.read, Opcode.METADATA: Metadata.read,
    Opcode.METADATA_INDEX: MetadataIndex.read, Opcode.STATISTICS: Statistics.read,
    Opcode.SUMMARY_OFFSET: SummaryOffset.read, Opcode.DATA_END: DataEnd.read,
}


class _BadRecord(Exception):
    """A record could not be read; the message says where and why."""


@dataclass(eq=False)
class View:
    """One recorded view: image, poses (``base`` frame, metres), intrinsics, joints.

    ``image`` (uint8, BGR or grey) and ``depth`` (float32 metres, NaN = none, or None) are
    decoded on first access and raise :class:`RecordingError` if the stored bytes are bad.
    """

    index: int
    timestamp_ns: int
    T_base_flange: np.ndarray
    T_flange_camera: np.ndarray
    intrinsics: Intrinsics | None
    joint_names: tuple[str, ...] = ()
    joint_positions: np.ndarray | None = None
    settle_s: float | None = None
    image_format: str = "png"
    image_size: tuple[int, int] | None = None  # (width, height) from the image header
    _image_data: bytes = field(default=b"", repr=False)
    _depth_msg: RawImage | None = field(default=None, repr=False)

    @property
    def T_base_camera(self) -> np.ndarray:
        """Pose of ``camera_optical`` in ``base``: ``T_base_flange @ T_flange_camera``."""
        return self.T_base_flange @ self.T_flange_camera

    @property
    def has_depth(self) -> bool:
        return self._depth_msg is not None

    @cached_property
    def image(self) -> np.ndarray:
        return _decode_image(self._image_data, self.image_format, self.intrinsics,
                             f"view {self.index}")

    @cached_property
    def depth(self) -> np.ndarray | None:
        if self._depth_msg is None:
            return None
        return _decode_depth(self._depth_msg, self.intrinsics, f"view {self.index}")


@dataclass(frozen=True, eq=False)
class Pair:
    """Two views that form a stereo pair, with the baselines the capture reported (metres)."""

    index: int
    left: View
    right: View
    commanded_baseline_m: float
    achieved_baseline_m: float
    direction: str


@dataclass(frozen=True)
class ChannelInfo:
    """A channel and the number of its messages that were read."""

    topic: str
    schema: str
    encoding: str
    messages: int


class Recording:
    """An opened recording: views, pairs, calibration, metadata and what went wrong.

    ``len(rec)``, ``rec[k]`` and iteration give the complete pairs in file order (``rec[k]`` is
    the k-th complete pair; ``Pair.index`` is the number the capture gave it). Access to pairs
    raises :class:`RecordingError` when the file has no camera calibration.
    """

    def __init__(self, path: Path, size_bytes: int) -> None:
        self.path = path
        self.size_bytes = size_bytes
        self.indexed = False
        self.truncated = False
        self.lost: list[str] = []  # what could not be read, one line each
        self.warnings: list[str] = []  # every problem found, including the lost items
        self.metadata: dict[str, str] = {}
        self.metadata_records: dict[str, dict[str, str]] = {}
        self.channels: list[ChannelInfo] = []
        self.views: list[View] = []
        self.pair_events: list[dict] = []  # as recorded, complete or not
        self.calibration: Intrinsics | None = None
        self.calibration_info: dict | None = None  # frame_id, distortion_model, ...
        self.point_clouds: list[RecordedPointCloud] = []
        self.start_ns: int | None = None
        self.end_ns: int | None = None
        self._pairs: list[Pair] = []

    @classmethod
    def open(cls, path: str | Path) -> Recording:
        """Read ``path``; raises :class:`RecordingError` only if it is not a readable MCAP file."""
        path = Path(path)
        try:
            with open(path, "rb") as f:
                size = f.seek(0, io.SEEK_END)
                f.seek(0)
                if size == 0:
                    raise RecordingError(f"{path} is empty (0 bytes), not an MCAP file")
                if f.read(len(MAGIC)) != MAGIC:
                    raise RecordingError(f"{path} is not an MCAP file (bad magic)")
                rec = cls(path, size)
                collector = _Collector()
                _scan(f, size, collector, rec)
        except OSError as err:
            raise RecordingError(f"cannot read recording {path}: {err.strerror or err}") from None
        _assemble(rec, collector)
        for text in rec.warnings:
            log.debug("%s: %s", path.name, text)
        return rec

    # ---------------------------------------------------------------------------- pair access
    @property
    def pairs(self) -> list[Pair]:
        """The complete pairs; raises :class:`RecordingError` without a camera calibration."""
        if self.calibration is None:
            raise RecordingError(f"{self.path} has no {S.TOPIC_CALIBRATION} message; the "
                                 "pairs need the camera intrinsics")
        return list(self._pairs)

    def require_pairs(self) -> list[Pair]:
        """The complete pairs; raises :class:`RecordingError` if there are none."""
        pairs = self.pairs
        if not pairs:
            raise RecordingError(f"{self.path} has no complete stereo pair ({len(self.views)} "
                                 f"complete view(s), {len(self.pair_events)} pair event(s))")
        return pairs

    def __len__(self) -> int:
        return len(self._pairs)

    def __getitem__(self, k: int) -> Pair:
        pairs = self.pairs
        try:
            return pairs[k]
        except IndexError:
            raise IndexError(f"pair {k} out of range: {self.path} has {len(pairs)} "
                             "complete pair(s)") from None

    def __iter__(self) -> Iterator[Pair]:
        return iter(self.pairs)

    def view(self, index: int) -> View:
        """The complete view numbered ``index``; raises :class:`RecordingError` if absent."""
        for v in self.views:
            if v.index == index:
                return v
        raise RecordingError(f"{self.path} has no complete view {index}")

    @property
    def duration_s(self) -> float | None:
        """Time from the first to the last message read (s), None without messages."""
        if self.start_ns is None or self.end_ns is None:
            return None
        return (self.end_ns - self.start_ns) / 1e9

    def _warn(self, text: str) -> None:
        self.warnings.append(text)

    def _lose(self, text: str) -> None:
        self.lost.append(text)
        self.warnings.append(text)


# ================================================================================ collecting
@dataclass(frozen=True)
class RecordedPointCloud:
    """A point cloud read from the file: points (N, 3) metres in ``frame_id``, BGR colours."""

    timestamp_ns: int
    frame_id: str
    topic: str
    points: np.ndarray
    colors_bgr: np.ndarray


@dataclass(frozen=True)
class _Calibration:
    t_ns: int
    intrinsics: Intrinsics
    frame_id: str
    distortion_model: str


@dataclass(frozen=True)
class _Frames:
    T_base_flange: np.ndarray
    T_flange_camera: np.ndarray
    quaternion_norms: dict[str, float]


class _Collector:
    """Decodes records one by one into per-topic tables; never raises on their content."""

    def __init__(self) -> None:
        self.schemas: dict[int, Schema] = {}
        self.channels: dict[int, Channel] = {}
        self.counts: Counter[int] = Counter()
        self.statistics: Statistics | None = None
        self.metadata: dict[str, dict[str, str]] = {}
        self.first_ns: int | None = None
        self.last_ns: int | None = None
        self.images: dict[int, tuple[str, bytes]] = {}
        self.depth: dict[int, RawImage] = {}
        self.tf: dict[int, _Frames] = {}
        self.calibrations: list[_Calibration] = []
        self.joints: dict[int, tuple[int, list[str], list[float]]] = {}
        self.view_events: dict[int, tuple[int, float]] = {}
        self.pair_events: list[dict] = []
        self.point_clouds: list[RecordedPointCloud] = []
        self._errors: dict[str, list] = {}  # topic -> [count, first reason]
        self._ignored: Counter[str] = Counter()
        self._mismatched: dict[str, tuple[str, str, int]] = {}
        self._duplicates: Counter[str] = Counter()
        self._no_channel = 0

    def add(self, record) -> None:
        if isinstance(record, Message):
            self._message(record)
        elif isinstance(record, Schema):
            self.schemas[record.id] = record
        elif isinstance(record, Channel):
            self.channels[record.id] = record
        elif isinstance(record, Metadata):
            self.metadata.setdefault(record.name, {str(k): str(v)
                                                   for k, v in record.metadata.items()})
        elif isinstance(record, Statistics):
            self.statistics = record

    def _message(self, m: Message) -> None:
        channel = self.channels.get(m.channel_id)
        if channel is None:
            self._no_channel += 1
            return
        self.counts[m.channel_id] += 1
        self.first_ns = m.log_time if self.first_ns is None else min(self.first_ns, m.log_time)
        self.last_ns = m.log_time if self.last_ns is None else max(self.last_ns, m.log_time)
        topic = channel.topic
        expected = S.EXPECTED_SCHEMAS.get(topic)
        if expected is None:
            if not topic.startswith(S.DERIVED_TOPIC_PREFIX):
                self._ignored[topic] += 1
            return
        schema = self.schemas.get(channel.schema_id)
        got = (schema.name if schema else "", channel.message_encoding)
        if got != expected:
            n = self._mismatched.get(topic, ("", "", 0))[2]
            self._mismatched[topic] = (*got, n + 1)
            return
        try:
            _DECODERS[topic](self, m.data, m.log_time, topic)
        except Exception as err:  # hostile payloads: protobuf, JSON, numpy, Intrinsics errors
            entry = self._errors.setdefault(topic, [0, _describe(err)])
            entry[0] += 1

    def _keep(self, table: dict, key: int, value, topic: str) -> None:
        if key in table:
            self._duplicates[topic] += 1
        else:
            table[key] = value

    # -------------------------------------------------------------------- per-topic decoders
    def image(self, data: bytes, t_ns: int, topic: str) -> None:
        msg = CompressedImage.FromString(data)
        fmt = msg.format.strip().lower()
        self._keep(self.images, t_ns, ("jpeg" if fmt == "jpg" else fmt, bytes(msg.data)), topic)

    def depth_image(self, data: bytes, t_ns: int, topic: str) -> None:
        msg = RawImage.FromString(data)
        if msg.encoding != S.DEPTH_ENCODING:
            raise ValueError(f"encoding {msg.encoding!r}, expected {S.DEPTH_ENCODING}")
        if msg.width < 1 or msg.height < 1 or msg.step != 4 * msg.width \
                or len(msg.data) != msg.step * msg.height:
            raise ValueError(f"{msg.width}x{msg.height} step {msg.step} does not fit "
                             f"{len(msg.data)} data bytes")
        self._keep(self.depth, t_ns, msg, topic)

    def frames(self, data: bytes, t_ns: int, topic: str) -> None:
        msg = FrameTransforms.FromString(data)
        found, norms = {}, {}
        for tr in msg.transforms:
            key = (tr.parent_frame_id, tr.child_frame_id)
            if key in _TF_NAMES and key not in found:
                found[key], norms[_TF_NAMES[key]] = _transform_matrix(tr)
        missing = [f"{p}->{c}" for (p, c) in _TF_NAMES if (p, c) not in found]
        if missing:
            raise ValueError(f"no {' or '.join(missing)} transform")
        frames = _Frames(found[(S.FRAME_BASE, S.FRAME_FLANGE)],
                         found[(S.FRAME_FLANGE, S.FRAME_CAMERA)], norms)
        self._keep(self.tf, t_ns, frames, topic)

    def calibration(self, data: bytes, t_ns: int, topic: str) -> None:
        msg = CameraCalibration.FromString(data)
        if len(msg.K) != 9:
            raise ValueError(f"K has {len(msg.K)} values, not 9")
        dist = np.array(msg.D, dtype=float) if len(msg.D) else np.zeros(5)
        intr = Intrinsics(int(msg.width), int(msg.height), np.array(msg.K).reshape(3, 3), dist)
        self.calibrations.append(_Calibration(t_ns, intr, msg.frame_id, msg.distortion_model))
        self.calibrations.sort(key=lambda c: c.t_ns)

    def joint_states(self, data: bytes, t_ns: int, topic: str) -> None:
        obj = _json_object(data)
        view, stamp = _int(obj, "view"), _int(obj, "timestamp_ns")
        names, positions = obj.get("names"), obj.get("positions")
        if not isinstance(names, list) or not all(isinstance(n, str) for n in names):
            raise ValueError("'names' is not a list of strings")
        if not isinstance(positions, list) or len(positions) != len(names) \
                or not all(_is_number(p) for p in positions):
            raise ValueError("'positions' is not a list of numbers matching 'names'")
        self._keep(self.joints, view, (stamp, names, [float(p) for p in positions]), topic)

    def event(self, data: bytes, t_ns: int, topic: str) -> None:
        obj = _json_object(data)
        kind = obj.get("event")
        if kind == "view":
            entry = (_int(obj, "timestamp_ns"), _number(obj, "settle_s"))
            self._keep(self.view_events, _int(obj, "view"), entry, topic)
        elif kind == "pair":
            event = {"pair": _int(obj, "pair"), "left_view": _int(obj, "left_view"),
                     "right_view": _int(obj, "right_view"),
                     "commanded_baseline_m": _number(obj, "commanded_baseline_m"),
                     "achieved_baseline_m": _number(obj, "achieved_baseline_m"),
                     "direction": str(obj.get("direction", ""))}
            if any(e["pair"] == event["pair"] for e in self.pair_events):
                self._duplicates[topic] += 1
            else:
                self.pair_events.append(event)
        else:
            raise ValueError(f"unknown event kind {kind!r}")

    def points(self, data: bytes, t_ns: int, topic: str) -> None:
        msg = PointCloud.FromString(data)
        pts, cols = _unpack_points(msg)
        self.point_clouds.append(RecordedPointCloud(t_ns, msg.frame_id, topic, pts, cols))

    # ------------------------------------------------------------------------------ reports
    def channel_table(self) -> list[tuple[str, str, str, int]]:
        rows = []
        for cid in sorted(self.channels):
            ch = self.channels[cid]
            schema = self.schemas.get(ch.schema_id)
            rows.append((ch.topic, schema.name if schema else "", ch.message_encoding,
                         self.counts[cid]))
        return rows

    def problems(self) -> list[str]:
        out = []
        if self._no_channel:
            out.append(f"{self._no_channel} message(s) refer to an undefined channel; ignored")
        for topic, n in self._ignored.items():
            out.append(f"ignored {n} message(s) on unknown topic {topic}")
        for topic, (name, enc, n) in self._mismatched.items():
            want = S.EXPECTED_SCHEMAS[topic]
            out.append(f"ignored {n} message(s) on {topic}: schema '{name}' ({enc}), expected "
                       f"'{want[0]}' ({want[1]})")
        for topic, (n, first) in self._errors.items():
            out.append(f"{n} message(s) on {topic} could not be decoded (first: {first})")
        for topic, n in self._duplicates.items():
            out.append(f"{n} duplicate message(s) on {topic} (same view or time); kept the first")
        return out

    def missing_against_statistics(self) -> list[str]:
        if self.statistics is None:
            return []
        out = []
        for cid, n in sorted(self.statistics.channel_message_counts.items()):
            got = self.counts.get(cid, 0)
            if got < n:
                ch = self.channels.get(cid)
                topic = ch.topic if ch else f"channel {cid}"
                out.append(f"{n - got} of {n} message(s) on {topic} listed in the index "
                           "could not be read")
        return out


_DECODERS = {
    S.TOPIC_IMAGE: _Collector.image, S.TOPIC_DEPTH: _Collector.depth_image,
    S.TOPIC_TF: _Collector.frames, S.TOPIC_CALIBRATION: _Collector.calibration,
    S.TOPIC_JOINT_STATES: _Collector.joint_states, S.TOPIC_EVENTS: _Collector.event,
    S.TOPIC_POINTS: _Collector.points,
}
_TF_NAMES = {(S.FRAME_BASE, S.FRAME_FLANGE): "base->tool0",
             (S.FRAME_FLANGE, S.FRAME_CAMERA): "tool0->camera_optical"}
_NUMERIC = {PackedElementField.UINT8: "u1", PackedElementField.INT8: "i1",
            PackedElementField.UINT16: "<u2", PackedElementField.INT16: "<i2",
            PackedElementField.UINT32: "<u4", PackedElementField.INT32: "<i4",
            PackedElementField.FLOAT32: "<f4", PackedElementField.FLOAT64: "<f8"}


def _transform_matrix(tr) -> tuple[np.ndarray, float]:
    """4x4 ``T_parent_child`` of a FrameTransform and the norm of its quaternion."""
    q = np.array([tr.rotation.x, tr.rotation.y, tr.rotation.z, tr.rotation.w])
    t = np.array([tr.translation.x, tr.translation.y, tr.translation.z])
    norm = float(np.linalg.norm(q))
    if not np.all(np.isfinite(q)) or not np.all(np.isfinite(t)) or norm < 1e-9:
        raise ValueError(f"{tr.parent_frame_id}->{tr.child_frame_id} is not a finite pose")
    return make_T(matrix_from_quaternion_xyzw(q), t), norm


def _unpack_points(msg) -> tuple[np.ndarray, np.ndarray]:
    fields = {f.name: f for f in msg.fields}
    names = [n for n in ("x", "y", "z", "red", "green", "blue") if n in fields]
    if not {"x", "y", "z"} <= set(names) or msg.point_stride < 1:
        raise ValueError("point cloud lacks x, y, z fields or a stride")
    dtype = np.dtype({"names": names, "formats": [_NUMERIC[fields[n].type] for n in names],
                      "offsets": [fields[n].offset for n in names],
                      "itemsize": msg.point_stride})
    if len(msg.data) % msg.point_stride:
        raise ValueError(f"{len(msg.data)} data bytes are not a multiple of the stride")
    arr = np.frombuffer(msg.data, dtype=dtype)
    pts = np.stack([arr[n].astype(float) for n in "xyz"], axis=1)
    cols = np.zeros((len(arr), 3), dtype=np.uint8)
    for k, n in enumerate(("blue", "green", "red")):
        if n in names:
            cols[:, k] = arr[n]
    return pts, cols


def _json_object(data: bytes) -> dict:
    obj = json.loads(data)
    if not isinstance(obj, dict):
        raise ValueError("not a JSON object")
    return obj


def _is_number(x) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool) and np.isfinite(x)


def _int(obj: dict, key: str) -> int:
    v = obj.get(key)
    if not isinstance(v, int) or isinstance(v, bool) or v < 0:
        raise ValueError(f"'{key}' is not an integer >= 0")
    return v


def _number(obj: dict, key: str) -> float:
    v = obj.get(key)
    if not _is_number(v):
        raise ValueError(f"'{key}' is not a finite number")
    return float(v)


def _image_size_from_header(data: bytes, fmt: str) -> tuple[int, int] | None:
    """(width, height) read from a PNG or JPEG header without decoding, None if unknown."""
    if fmt == "png" and data[:8] == b"\x89PNG\r\n\x1a\n" and data[12:16] == b"IHDR":
        w, h = struct.unpack(">II", data[16:24])
        return (w, h)
    if fmt == "jpeg" and data[:2] == b"\xff\xd8":
        return _jpeg_size(data)
    return None


def _jpeg_size(data: bytes) -> tuple[int, int] | None:
    i = 2
    while i + 9 <= len(data):
        if data[i] != 0xFF:
            return None
        marker = data[i + 1]
        if marker == 0xFF:  # fill byte
            i += 1
            continue
        if 0xC0 <= marker <= 0xCF and marker not in (0xC4, 0xC8, 0xCC):
            h, w = struct.unpack(">HH", data[i + 5:i + 9])
            return (w, h)
        if marker in (0x01, 0xD8) or 0xD0 <= marker <= 0xD7:
            i += 2
            continue
        i += 2 + struct.unpack(">H", data[i + 2:i + 4])[0]
    return None


# ================================================================================= low level
def _read_record(f, offset: int, end: int) -> tuple[int, bytes]:
    """Opcode and body of the record at ``offset``; it must end by byte ``end``."""
    f.seek(offset)
    head = f.read(RECORD_HEADER)
    if len(head) < RECORD_HEADER:
        raise _BadRecord(f"the file ends inside a record header at byte {offset}")
    opcode, length = struct.unpack("<BQ", head)
    room = end - offset - RECORD_HEADER
    if length > room:
        raise _BadRecord(f"record at byte {offset} (opcode 0x{opcode:02x}) claims {length} "
                         f"bytes but only {room} remain")
    return opcode, f.read(length)


def _parse(opcode: int, body: bytes):
    """The mcap record object for a record body (None for types we skip)."""
    stream = ReadDataStream(io.BytesIO(body))
    if opcode == Opcode.MESSAGE:
        return Message.read(stream, len(body))
    parser = _PARSERS.get(opcode)
    return parser(stream) if parser else None


def _chunk_records(chunk: Chunk) -> list:
    if chunk.compression not in ("", "zstd", "lz4"):
        raise _BadRecord(f"unsupported chunk compression {chunk.compression!r}")
    if chunk.uncompressed_size > MAX_CHUNK_BYTES:
        raise _BadRecord(f"chunk claims {chunk.uncompressed_size} uncompressed bytes "
                         f"(limit {MAX_CHUNK_BYTES})")
    return breakup_chunk(chunk, validate_crc=True)


def _read_one(f, offset: int, end: int) -> tuple[object, list, int]:
    """Record at ``offset``: (record, records to collect, offset after it).

    Any failure, whatever the decoder raised, becomes :class:`_BadRecord`.
    """
    try:
        opcode, body = _read_record(f, offset, end)
        record = _parse(opcode, body)
        inner = _chunk_records(record) if isinstance(record, Chunk) else [record]
    except _BadRecord:
        raise
    except Exception as err:  # hostile bytes can make mcap/zstd/lz4 raise almost anything
        raise _BadRecord(f"record at byte {offset} is damaged ({_describe(err)})") from None
    return record, [r for r in inner if r is not None], offset + RECORD_HEADER + len(body)


def _describe(err: BaseException) -> str:
    text = str(err).strip().splitlines()[0] if str(err).strip() else ""
    return f"{type(err).__name__}: {text[:120]}" if text else type(err).__name__


# ==================================================================================== scanning
def _scan(f, size: int, collector: _Collector, rec: Recording) -> None:
    """Feed every readable record to ``collector``, by index if possible, else by streaming."""
    try:
        summary = _read_summary(f, size)
    except _BadRecord as err:
        rec._warn(f"the index (summary section) is damaged ({err}); read by streaming")
        summary = None
    rec.indexed = summary is not None
    if summary is None:
        rec._warn("no index (summary section): the recording was not finished cleanly; "
                  "read by streaming")
    elif any(isinstance(r, ChunkIndex) for r in summary):
        _scan_indexed(f, size, summary, collector, rec)
        return
    _scan_stream(f, size, collector, rec)  # also for unchunked files, whose index has no chunks


def _read_summary(f, size: int) -> list | None:
    """Summary-section records, or None if the file has no summary (raises _BadRecord)."""
    if size < 2 * len(MAGIC) + FOOTER_RECORD:
        return None
    f.seek(size - len(MAGIC))
    if f.read(len(MAGIC)) != MAGIC:
        return None  # unfinished or cut short
    footer_at = size - len(MAGIC) - FOOTER_RECORD
    footer, _, _ = _read_one(f, footer_at, size - len(MAGIC))
    if not isinstance(footer, Footer):
        raise _BadRecord("the closing magic is not preceded by a footer")
    start = footer.summary_start
    if start == 0:
        return None
    if not len(MAGIC) < start <= footer_at:
        raise _BadRecord(f"summary start {start} lies outside the file")
    if footer.summary_crc:
        f.seek(start)
        crc = zlib.crc32(f.read(size - len(MAGIC) - 4 - start))
        if crc != footer.summary_crc:
            raise _BadRecord("summary CRC mismatch")
    records, offset = [], start
    while offset < footer_at:
        record, _, offset = _read_one(f, offset, footer_at)
        records.append(record)
    return records


def _scan_indexed(f, size: int, summary: list, collector: _Collector, rec: Recording) -> None:
    data_end = size
    for record in summary:
        if not isinstance(record, (ChunkIndex, MetadataIndex)):
            collector.add(record)
    for index in (r for r in summary if isinstance(r, MetadataIndex)):
        for r in _try_read(f, index.offset, data_end, rec, f"metadata record '{index.name}'"):
            collector.add(r)
    chunks = sorted((r for r in summary if isinstance(r, ChunkIndex)),
                    key=lambda c: c.chunk_start_offset)
    for index in chunks:
        what = (f"chunk at byte {index.chunk_start_offset} ({index.chunk_length} bytes, "
                f"log time {index.message_start_time}..{index.message_end_time} ns)")
        for r in _try_read(f, index.chunk_start_offset, data_end, rec, what):
            collector.add(r)


def _try_read(f, offset: int, end: int, rec: Recording, what: str) -> list:
    try:
        _, records, _ = _read_one(f, offset, end)
    except _BadRecord as err:
        rec._lose(f"{what} could not be read: {err}")
        return []
    return records


def _scan_stream(f, size: int, collector: _Collector, rec: Recording) -> None:
    offset = len(MAGIC)
    unknown = 0
    while True:
        if offset >= size:
            rec.truncated = True
            rec._lose(f"the file ends after {offset} bytes without a footer (capture killed or "
                      "still running); everything up to there was read")
            break
        try:
            record, inner, next_offset = _read_one(f, offset, size)
        except _BadRecord as err:
            rec.truncated = True
            rec._lose(f"reading stopped at byte {offset} of {size}: {err}; the last "
                      f"{size - offset} bytes were not read")
            break
        unknown += record is None
        for r in inner:
            collector.add(r)
        offset = next_offset
        if isinstance(record, Footer):
            break
    if unknown:
        rec._warn(f"skipped {unknown} record(s) of unknown type")


# =================================================================================== assembly
def _assemble(rec: Recording, col: _Collector) -> None:
    """Turn collected messages into views, pairs and warnings."""
    rec.metadata_records = dict(col.metadata)
    rec.metadata = dict(col.metadata.get(S.METADATA_NAME, {}))
    if S.METADATA_NAME not in col.metadata:
        rec._warn(f"no '{S.METADATA_NAME}' metadata record (robot, mount, capture settings)")
    rec.channels = [ChannelInfo(*info) for info in col.channel_table()]
    rec.start_ns, rec.end_ns = col.first_ns, col.last_ns
    rec.point_clouds = list(col.point_clouds)
    for text in col.problems():
        rec._warn(text)
    for text in col.missing_against_statistics():
        rec._lose(text)
    _set_calibration(rec, col)
    _build_views(rec, col)
    _build_pairs(rec, col)
    if col.first_ns is None:
        rec._warn("the recording holds no readable message")


def _set_calibration(rec: Recording, col: _Collector) -> None:
    if not col.calibrations:
        rec._warn(f"no camera calibration ({S.TOPIC_CALIBRATION}): pairs cannot be used")
        return
    first = col.calibrations[0]
    rec.calibration = first.intrinsics
    rec.calibration_info = {"frame_id": first.frame_id,
                            "distortion_model": first.distortion_model}
    if first.frame_id != S.FRAME_CAMERA:
        rec._warn(f"calibration frame_id is '{first.frame_id}', expected '{S.FRAME_CAMERA}'")


def _intrinsics_at(col: _Collector, t_ns: int) -> Intrinsics | None:
    best = None
    for cal in col.calibrations:  # sorted by time: the latest one not after t_ns
        if best is None or cal.t_ns <= t_ns:
            best = cal
    return None if best is None else best.intrinsics


def _build_views(rec: Recording, col: _Collector) -> None:
    claimed: set[int] = set()
    for index in sorted(col.view_events):
        t_ns, settle_s = col.view_events[index]
        missing = [topic for topic, table in ((S.TOPIC_IMAGE, col.images), (S.TOPIC_TF, col.tf))
                   if t_ns not in table]
        if missing:
            rec._lose(f"view {index} is incomplete (no {' or '.join(missing)} message at "
                      f"{t_ns} ns); skipped")
            continue
        claimed.add(t_ns)
        rec.views.append(_make_view(rec, col, index, t_ns, settle_s))
    for topic, table in ((S.TOPIC_IMAGE, col.images), (S.TOPIC_TF, col.tf),
                         (S.TOPIC_DEPTH, col.depth)):
        orphans = len(set(table) - claimed)
        if orphans:
            rec._lose(f"{orphans} message(s) on {topic} belong to no complete view (a view "
                      "cut short?)")


def _make_view(rec: Recording, col: _Collector, index: int, t_ns: int,
               settle_s: float) -> View:
    fmt, data = col.images[t_ns]
    frames: _Frames = col.tf[t_ns]
    intr = _intrinsics_at(col, t_ns)
    joints = col.joints.get(index)
    if joints is None or joints[0] != t_ns:
        rec._warn(f"view {index} has no joint states on {S.TOPIC_JOINT_STATES}")
        joints = None
    size = _image_size_from_header(data, fmt)
    if size is not None and intr is not None and size != intr.size:
        rec._warn(f"view {index}: image is {size[0]}x{size[1]} but the calibration says "
                  f"{intr.width}x{intr.height}")
    for name, norm in frames.quaternion_norms.items():
        if abs(norm - 1.0) > 1e-6:
            rec._warn(f"view {index}: {name} rotation quaternion has norm {norm:.6f}, not 1 "
                      "(not a rotation)")
    return View(index=index, timestamp_ns=t_ns, T_base_flange=frames.T_base_flange,
                T_flange_camera=frames.T_flange_camera, intrinsics=intr,
                joint_names=tuple(joints[1]) if joints else (),
                joint_positions=np.array(joints[2], dtype=float) if joints else None,
                settle_s=settle_s, image_format=fmt, image_size=size, _image_data=data,
                _depth_msg=col.depth.get(t_ns))


def _build_pairs(rec: Recording, col: _Collector) -> None:
    views = {v.index: v for v in rec.views}
    for event in col.pair_events:
        rec.pair_events.append(event)
        left, right = views.get(event["left_view"]), views.get(event["right_view"])
        if left is None or right is None:
            gone = [k for k, v in ((event["left_view"], left), (event["right_view"], right))
                    if v is None]
            rec._lose(f"pair {event['pair']} is incomplete (view {', '.join(map(str, gone))} "
                      "missing); skipped")
            continue
        pair = Pair(event["pair"], left, right, event["commanded_baseline_m"],
                    event["achieved_baseline_m"], event["direction"])
        _check_baseline(rec, pair)
        rec._pairs.append(pair)


def _check_baseline(rec: Recording, pair: Pair) -> None:
    from_poses = float(np.linalg.norm(pair.right.T_base_camera[:3, 3]
                                      - pair.left.T_base_camera[:3, 3]))
    if abs(from_poses - pair.achieved_baseline_m) > BASELINE_TOLERANCE_M:
        rec._warn(f"pair {pair.index}: achieved baseline {pair.achieved_baseline_m * 1000:.3f} mm "
                  f"in the event but {from_poses * 1000:.3f} mm from the {S.TOPIC_TF} poses "
                  f"(limit {BASELINE_TOLERANCE_M * 1000:.1f} mm)")


# =================================================================================== decoding
def _decode_image(data: bytes, fmt: str, intr: Intrinsics | None, what: str) -> np.ndarray:
    """Decode a CompressedImage payload to uint8 BGR (or grey); RecordingError if bad."""
    size = _image_size_from_header(data, fmt)
    if size is not None:
        if size[0] * size[1] > MAX_IMAGE_PIXELS:
            raise RecordingError(f"{what}: image header claims {size[0]}x{size[1]} pixels "
                                 f"(limit {MAX_IMAGE_PIXELS})")
        _check_size(size, intr, what)
    try:
        img = cv2.imdecode(np.frombuffer(data, dtype=np.uint8), cv2.IMREAD_UNCHANGED)
    except Exception as err:  # OpenCV raises cv2.error or MemoryError on hostile data
        raise RecordingError(f"{what}: {fmt} image could not be decoded "
                             f"({_describe(err)})") from None
    if img is None:
        raise RecordingError(f"{what}: {fmt} image could not be decoded ({len(data)} bytes)")
    if img.dtype != np.uint8:
        raise RecordingError(f"{what}: image is {img.dtype}; armstereo expects 8-bit images")
    if img.ndim == 3 and img.shape[2] == 4:
        img = cv2.cvtColor(img, cv2.COLOR_BGRA2BGR)
    _check_size((img.shape[1], img.shape[0]), intr, what)
    return img


def _check_size(size: tuple[int, int], intr: Intrinsics | None, what: str) -> None:
    if intr is not None and tuple(size) != intr.size:
        raise RecordingError(f"{what}: image is {size[0]}x{size[1]} but the calibration says "
                             f"{intr.width}x{intr.height}")


def _decode_depth(msg: RawImage, intr: Intrinsics | None, what: str) -> np.ndarray:
    depth = np.frombuffer(msg.data, dtype="<f4").reshape(msg.height, msg.width)
    _check_size((msg.width, msg.height), intr, what + " depth")
    return depth.astype(np.float32)  # a native, writable copy

