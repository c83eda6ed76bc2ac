"""Collecting: decode each MCAP record into per-topic tables, never raising on content.

The :class:`Collector` is fed records by :mod:`armstereo.recording.mcap_scan`; hostile or damaged
payloads become counted problems, reported one line each.
"""

from __future__ import annotations

import json
from collections import Counter
from dataclasses import dataclass

import numpy as np
from foxglove_schemas_protobuf.CameraCalibration_pb2 import CameraCalibration
from foxglove_schemas_protobuf.CompressedImage_pb2 import CompressedImage
from foxglove_schemas_protobuf.FrameTransforms_pb2 import FrameTransforms
from foxglove_schemas_protobuf.PackedElementField_pb2 import PackedElementField
from foxglove_schemas_protobuf.PointCloud_pb2 import PointCloud
from foxglove_schemas_protobuf.RawImage_pb2 import RawImage
from mcap.records import Channel, Message, Metadata, Schema, Statistics

from armstereo import camera_settings
from armstereo.camera_model import Intrinsics
from armstereo.errors import RecordingError
from armstereo.recording import schemas as S
from armstereo.recording.contents import RecordedPointCloud
from armstereo.transforms import make_T, matrix_from_quaternion_xyzw


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


class Collector:
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
        self.view_events: dict[int, tuple[int, float, np.ndarray | None]] = {}
        self.pair_events: list[dict] = []
        self.device_fields: dict[int, dict] = {}  # view -> camera_settings, device time, frame
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
            entry = self._errors.setdefault(topic, [0, describe(err)])
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
            entry = (_int(obj, "timestamp_ns"), _number(obj, "settle_s"),
                     _controller_pose(obj))
            view = _int(obj, "view")
            self._keep(self.view_events, view, entry, topic)
            self._device_fields(view, obj)
        elif kind == "pair":
            event = {"pair": _int(obj, "pair"), "left_view": _int(obj, "left_view"),
                     "right_view": _int(obj, "right_view"),
                     "commanded_baseline_m": _number(obj, "commanded_baseline_m"),
                     "achieved_baseline_m": _number(obj, "achieved_baseline_m"),
                     "direction": str(obj.get("direction", "")),
                     "viewpoint": _int(obj, "viewpoint") if "viewpoint" in obj else None}
            if any(e["pair"] == event["pair"] for e in self.pair_events):
                self._duplicates[topic] += 1
            else:
                self.pair_events.append(event)
        else:
            raise ValueError(f"unknown event kind {kind!r}")

    def _device_fields(self, view: int, obj: dict) -> None:
        """The view event's optional camera report; a malformed one is dropped (counted), the
        view is kept."""
        if view in self.device_fields:
            return
        try:
            fields = {"camera_settings": camera_settings.validate(obj.get("camera_settings")),
                      "device_timestamp_ns": _optional_int(obj, "device_timestamp_ns"),
                      "device_frame": _optional_int(obj, "device_frame")}
        except (ValueError, RecordingError) as err:
            entry = self._errors.setdefault(S.TOPIC_EVENTS + " camera report", [0, describe(err)])
            entry[0] += 1
            return
        self.device_fields[view] = fields

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
    S.TOPIC_IMAGE: Collector.image, S.TOPIC_DEPTH: Collector.depth_image,
    S.TOPIC_TF: Collector.frames, S.TOPIC_CALIBRATION: Collector.calibration,
    S.TOPIC_JOINT_STATES: Collector.joint_states, S.TOPIC_EVENTS: Collector.event,
    S.TOPIC_POINTS: Collector.points,
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



def _optional_int(obj: dict, key: str) -> int | None:
    return _int(obj, key) if key in obj else None


def _controller_pose(obj: dict) -> np.ndarray | None:
    """The view event's optional ``controller_T_base_tool0`` (16 numbers, row-major 4x4)."""
    v = obj.get("controller_T_base_tool0")
    if v is None:
        return None
    if not isinstance(v, list) or len(v) != 16 or not all(_is_number(x) for x in v):
        raise ValueError("'controller_T_base_tool0' is not 16 finite numbers")
    return np.array(v, dtype=float).reshape(4, 4)


def describe(err: BaseException) -> str:
    """One short line naming an exception (for problem reports)."""
    text = str(err).strip().splitlines()[0] if str(err).strip() else ""
    return f"{type(err).__name__}: {text[:120]}" if text else type(err).__name__
