"""``armstereo export REC.mcap --to ros2 --out BAG``: any armstereo MCAP as a ROS 2 bag.

Every message of the recording becomes the standard ROS 2 message at the same log time, its
header stamp the Foxglove message's own timestamp (a view's exposure time):

- ``/camera/image`` (CompressedImage) -> ``sensor_msgs/msg/Image`` ``bgr8``/``mono8``; with
  ``compressed``, ``/camera/image/compressed`` ``CompressedImage`` holding the PNG/JPEG bytes;
- ``/camera/calibration`` -> ``/camera/camera_info`` ``CameraInfo``, at the calibration's time
  and beside every image;
- ``/tf`` -> ``/tf`` ``tf2_msgs/msg/TFMessage``; a transform that never changes (the camera
  mount ``tool0 -> camera_optical``) goes once onto ``/tf_static``;
- ``/joint_states`` (JSON) -> ``sensor_msgs/msg/JointState``; ``/capture/events`` (JSON) ->
  ``std_msgs/msg/String`` holding the JSON as recorded;
- RawImage (depth ``32FC1``) -> ``sensor_msgs/msg/Image`` with the same encoding;
- PointCloud, Grid (height map) -> ``sensor_msgs/msg/PointCloud2`` x, y, z, rgb;
- SceneUpdate -> on ``/fusion/mesh`` ``visualization_msgs/msg/Marker`` (TRIANGLE_LIST), on
  other topics ``MarkerArray`` (one Marker per primitive, one message per update);
- VoxelGrid (occupancy) -> ``visualization_msgs/msg/Marker`` CUBE_LIST of occupied voxels.

The ``armstereo`` metadata record goes into ``metadata.yaml``'s ``custom_data`` as
``armstereo.<key>``, so an import of the bag restores it.
"""

from __future__ import annotations

import importlib
import json
import logging
from collections import Counter
from dataclasses import dataclass, replace
from pathlib import Path

import cv2
import numpy as np
from mcap.reader import make_reader

from armstereo.camera_model import Intrinsics
from armstereo.errors import ArmstereoError, ConfigError, RecordingError
from armstereo.recording import Recording
from armstereo.recording import schemas as S
from armstereo.ros2 import foxglove_in as F
from armstereo.ros2 import markers as M
from armstereo.ros2 import messages as msgs
from armstereo.ros2 import types as R
from armstereo.ros2.bag_writer import BagWriter, check_destination
from armstereo.transforms import make_T, matrix_from_quaternion_xyzw

log = logging.getLogger(__name__)

CUSTOM_PREFIX = "armstereo."  # metadata.yaml custom_data keys holding the metadata record
CAMERA_INFO_TOPIC = "/camera/camera_info"
SINGLE_MARKER_TOPICS = ("/fusion/mesh",)  # one Marker per message; other scenes: MarkerArray
KINDS = {"scan": "scan", "reconstruction": "reconstruction", "fusion": "fusion",
         "scene_analysis": "scene"}


@dataclass(frozen=True, kw_only=True)
class ExportOptions:
    """``distro``: humble (plays on Humble and Jazzy) or jazzy; ``compressed``: keep the
    recorded PNG/JPEG bytes as CompressedImage instead of raw Image; ``camera_frame``: the
    name the camera's optical frame gets (armstereo's is ``camera_optical``)."""

    distro: str = R.DEFAULT_DISTRO
    compressed: bool = False
    camera_frame: str = S.FRAME_CAMERA
    force: bool = False

    def __post_init__(self) -> None:
        R.distro(self.distro)
        if not self.camera_frame.strip() or self.camera_frame.startswith("/"):
            raise ConfigError(f"--camera-frame must be a tf2 frame name (no leading '/'), not "
                              f"{self.camera_frame!r}")


def recording_kind(metadata: dict[str, str]) -> str:
    """capture, scan, calibration, reconstruction, fusion or scene (from the metadata)."""
    if metadata.get("purpose") == "calibration":
        return "calibration"
    return KINDS.get(metadata.get("kind", ""), "capture")


def export_recording(src: str | Path, out: str | Path,
                     options: ExportOptions | None = None) -> dict:
    """Write ``src`` (an armstereo MCAP) as the bag folder ``out``; returns the report
    (``bag``, ``kind``, ``distro``, ``topics`` {topic: {type, messages}}, ``skipped``,
    ``warnings``). RecordingError for an unreadable recording, OutputError if the bag cannot
    be written, ConfigError for a bad destination."""
    options = options or ExportOptions()
    src, out = Path(src), Path(out)
    check_destination(out, options.force)
    rec = Recording.open(src)
    if not rec.channels:
        raise RecordingError(f"{src} holds no channel; nothing to export")
    kind = recording_kind(rec.metadata)
    custom = {CUSTOM_PREFIX + k: v for k, v in rec.metadata.items()}
    custom.update({"armstereo.source_recording": src.name, "armstereo.recording_kind": kind})
    with BagWriter(out, distro=options.distro, custom_data=custom) as bag:
        ex = _Exporter(bag, options, _static_edges(src))
        for schema, channel, message in _messages(src, ex.warnings):
            ex.add(schema, channel.topic, message.log_time, message.data)
    topics = {t: {"type": bag.types[t], "messages": n} for t, n in bag.counts.items()}
    return {"bag": str(out), "kind": kind, "distro": options.distro, "storage": "mcap",
            "source": str(src), "topics": topics, "skipped": dict(ex.skipped),
            "warnings": _reader_warnings(rec, kind) + ex.warnings}


def _reader_warnings(rec: Recording, kind: str) -> list[str]:
    """What the recording reader found wrong; for a fusion or scene MCAP only what it could
    not read (its views and calibration are not that file's business)."""
    if kind in ("fusion", "scene"):
        return list(rec.lost)
    return [w for w in rec.warnings if "on unknown topic" not in w]


def _messages(path: Path, warnings: list[str]):
    """(schema, channel, message) in log-time order; a recording cut short (no index, a
    damaged end) is exported up to where it can be read, with a warning."""
    with open(path, "rb") as f:
        it = None
        while True:
            try:
                if it is None:
                    it = make_reader(f).iter_messages(log_time_order=True)
                item = next(it)
            except StopIteration:
                return
            except Exception as err:  # noqa: BLE001 - mcap/zstd/protobuf raise many kinds
                warnings.append(f"reading {path.name} stopped early ({type(err).__name__}: "
                                f"{err}); exported what came before")
                return
            yield item


def _protobuf(schema, data: bytes):
    short = schema.name.removeprefix("foxglove.")
    module = importlib.import_module(f"foxglove_schemas_protobuf.{short}_pb2")
    return getattr(module, short).FromString(data)


def _transform_matrix(tr) -> np.ndarray:
    q = np.array([tr.rotation.x, tr.rotation.y, tr.rotation.z, tr.rotation.w])
    return make_T(matrix_from_quaternion_xyzw(q / np.linalg.norm(q)),
                  [tr.translation.x, tr.translation.y, tr.translation.z])


def _static_edges(path: Path) -> dict[tuple[str, str], np.ndarray]:
    """Transforms (parent, child) that hold one value throughout ``/tf`` while another one
    changes, and the camera mount ``tool0 -> camera_optical`` when it never changes."""
    values: dict[tuple[str, str], list[np.ndarray]] = {}
    for schema, channel, message in _messages(path, []):
        if channel.topic != S.TOPIC_TF or schema is None \
                or schema.name != "foxglove.FrameTransforms":
            continue
        try:
            msg = _protobuf(schema, message.data)
            for tr in msg.transforms:
                values.setdefault((tr.parent_frame_id, tr.child_frame_id), []).append(
                    _transform_matrix(tr))
        except Exception:  # noqa: BLE001 - the conversion pass reports bad messages
            continue
    constant = {edge for edge, Ts in values.items()
                if all(np.array_equal(T, Ts[0]) for T in Ts)}
    moving = len(constant) < len(values)
    return {edge: values[edge][0] for edge in constant
            if moving or edge == (S.FRAME_FLANGE, S.FRAME_CAMERA)}


class _Exporter:
    """Converts one recorded message at a time and writes it to the bag."""

    def __init__(self, bag: BagWriter, options: ExportOptions,
                 static: dict[tuple[str, str], np.ndarray]) -> None:
        self.bag, self.options, self.store = bag, options, bag.store
        self.static = static
        self.static_written = False
        self.calibration: tuple[Intrinsics, str] | None = None
        self.skipped: Counter[str] = Counter()
        self.warnings: list[str] = []
        self._failed: Counter[str] = Counter()

    def frame(self, name: str) -> str:
        return self.options.camera_frame if name == S.FRAME_CAMERA else name

    def add(self, schema, topic: str, t_ns: int, data: bytes) -> None:
        if not self.static_written:
            self._write_static(t_ns)
        name = schema.name if schema is not None else ""
        handler = _HANDLERS.get(name)
        if handler is None:
            self.skipped[f"{topic} ({name or 'no schema'})"] += 1
            return
        try:
            msg = json.loads(data) if name.startswith("armstereo.") else _protobuf(schema, data)
            handler(self, topic, t_ns, msg, data)
        except ArmstereoError:
            raise
        except Exception as err:  # noqa: BLE001 - a damaged message must not end the export
            if not self._failed[topic]:
                self.warnings.append(f"a message on {topic} could not be converted "
                                     f"({type(err).__name__}: {err}); skipped")
            self._failed[topic] += 1

    def _write_static(self, t_ns: int) -> None:
        self.static_written = True
        if not self.static:
            return
        tfs = [msgs.transform(self.store, T, self.frame(p), self.frame(c), t_ns)
               for (p, c), T in self.static.items()]
        self.bag.write(R.TOPIC_TF_STATIC, R.TF_MESSAGE, t_ns, msgs.tf_message(self.store, tfs),
                       qos="static")

    # ------------------------------------------------------------------- one per schema
    def compressed_image(self, topic: str, t_ns: int, msg, data: bytes) -> None:
        stamp = F.stamp_ns(msg.timestamp) if msg.HasField("timestamp") else t_ns
        frame = self.frame(msg.frame_id)
        img = cv2.imdecode(np.frombuffer(msg.data, np.uint8), cv2.IMREAD_UNCHANGED)
        if img is None:
            raise ValueError(f"{msg.format} image could not be decoded")
        if img.ndim == 3 and img.shape[2] == 4:
            img = cv2.cvtColor(img, cv2.COLOR_BGRA2BGR)
        if self.options.compressed:
            fmt = "jpeg" if msg.format.lower() in ("jpg", "jpeg") else msg.format.lower()
            self.bag.write(topic + "/compressed", R.COMPRESSED_IMAGE, t_ns,
                           msgs.compressed_image(self.store, msg.data, fmt, img.ndim == 2,
                                                 stamp, frame))
        else:
            self.bag.write(topic, R.IMAGE, t_ns, msgs.image(self.store, img, stamp, frame))
        if topic == S.TOPIC_IMAGE and self.calibration is not None:
            self._camera_info(self.calibration[0], stamp, t_ns, frame)

    def raw_image(self, topic: str, t_ns: int, msg, data: bytes) -> None:
        stamp = F.stamp_ns(msg.timestamp) if msg.HasField("timestamp") else t_ns
        image = R.msg_class(self.store, R.IMAGE)(
            header=R.header(self.store, stamp, self.frame(msg.frame_id)), height=msg.height,
            width=msg.width, encoding=msg.encoding, is_bigendian=0, step=msg.step,
            data=np.frombuffer(msg.data, dtype=np.uint8))
        if len(msg.data) != msg.step * msg.height:
            raise ValueError(f"{msg.width}x{msg.height} step {msg.step} does not fit "
                             f"{len(msg.data)} bytes")
        self.bag.write(topic, R.IMAGE, t_ns, image)

    def calibration_msg(self, topic: str, t_ns: int, msg, data: bytes) -> None:
        intr = Intrinsics(int(msg.width), int(msg.height), np.array(msg.K).reshape(3, 3),
                          np.array(msg.D, dtype=float) if len(msg.D) else np.zeros(5))
        self.calibration = (intr, msg.frame_id)
        stamp = F.stamp_ns(msg.timestamp) if msg.HasField("timestamp") else t_ns
        self._camera_info(intr, stamp, t_ns, self.frame(msg.frame_id))

    def _camera_info(self, intr: Intrinsics, stamp: int, t_ns: int, frame: str) -> None:
        self.bag.write(CAMERA_INFO_TOPIC, R.CAMERA_INFO, t_ns,
                       msgs.camera_info(self.store, intr, stamp, frame))

    def frames(self, topic: str, t_ns: int, msg, data: bytes) -> None:
        tfs = [msgs.transform(self.store, _transform_matrix(tr), self.frame(tr.parent_frame_id),
                              self.frame(tr.child_frame_id),
                              F.stamp_ns(tr.timestamp) if tr.HasField("timestamp") else t_ns)
               for tr in msg.transforms
               if (tr.parent_frame_id, tr.child_frame_id) not in self.static]
        if tfs:
            self.bag.write(R.TOPIC_TF, R.TF_MESSAGE, t_ns, msgs.tf_message(self.store, tfs),
                           qos="tf")

    def joints(self, topic: str, t_ns: int, obj, data: bytes) -> None:
        stamp = int(obj.get("timestamp_ns", t_ns))
        self.bag.write(topic, R.JOINT_STATE, t_ns,
                       msgs.joint_state(self.store, obj["names"], obj["positions"], stamp))

    def event(self, topic: str, t_ns: int, obj, data: bytes) -> None:
        self.bag.write(topic, R.STRING, t_ns, msgs.string(self.store, data.decode()))

    def cloud(self, topic: str, t_ns: int, msg, data: bytes) -> None:
        pts, cols = F.point_cloud(msg)
        stamp = F.stamp_ns(msg.timestamp) if msg.HasField("timestamp") else t_ns
        self.bag.write(topic, R.POINT_CLOUD2, t_ns,
                       msgs.point_cloud2(self.store, pts, cols, stamp, self.frame(msg.frame_id)))

    def grid(self, topic: str, t_ns: int, msg, data: bytes) -> None:
        pts, cols = F.grid_points(msg)
        stamp = F.stamp_ns(msg.timestamp) if msg.HasField("timestamp") else t_ns
        self.bag.write(topic, R.POINT_CLOUD2, t_ns,
                       msgs.point_cloud2(self.store, pts, cols, stamp, self.frame(msg.frame_id)))

    def voxels(self, topic: str, t_ns: int, msg, data: bytes) -> None:
        stamp = F.stamp_ns(msg.timestamp) if msg.HasField("timestamp") else t_ns
        spec = F.voxel_marker(msg, stamp, topic.rsplit("/", 1)[-1])
        spec = _renamed(spec, self.frame(spec.frame_id))
        self.bag.write(topic, R.MARKER, t_ns, raw=M.encode_marker(spec))

    def scene(self, topic: str, t_ns: int, msg, data: bytes) -> None:
        specs = [_renamed(s, self.frame(s.frame_id)) for s in F.scene_markers(msg, t_ns)]
        if topic in SINGLE_MARKER_TOPICS:
            for spec in specs:
                self.bag.write(topic, R.MARKER, t_ns, raw=M.encode_marker(spec))
        else:
            self.bag.write(topic, R.MARKER_ARRAY, t_ns, raw=M.encode_marker_array(specs))


def _renamed(spec: M.MarkerSpec, frame: str) -> M.MarkerSpec:
    return spec if frame == spec.frame_id else replace(spec, frame_id=frame)


_HANDLERS = {
    "foxglove.CompressedImage": _Exporter.compressed_image,
    "foxglove.RawImage": _Exporter.raw_image,
    "foxglove.CameraCalibration": _Exporter.calibration_msg,
    "foxglove.FrameTransforms": _Exporter.frames,
    "foxglove.PointCloud": _Exporter.cloud,
    "foxglove.Grid": _Exporter.grid,
    "foxglove.VoxelGrid": _Exporter.voxels,
    "foxglove.SceneUpdate": _Exporter.scene,
    S.JOINT_STATES_SCHEMA_NAME: _Exporter.joints,
    S.CAPTURE_EVENT_SCHEMA_NAME: _Exporter.event,
}
