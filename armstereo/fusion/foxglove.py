"""An MCAP of the fused scan for Foxglove: the mesh, the fused cloud and the camera's tour.

Topics (all in frame ``base``; protobuf, Foxglove schemas):

- ``/fusion/mesh`` (``foxglove.SceneUpdate``): entity ``mesh``, one ``TriangleListPrimitive``
  with per-vertex colours and an index list;
- ``/fusion/points`` (``foxglove.PointCloud``): the fused cloud, float32 xyz + rgba;
- ``/fusion/views`` (``foxglove.SceneUpdate``): per recorded view a camera frustum (entity
  ``view_K``, a line list at the view's camera pose, labelled with its view and pair) and
  entity ``tour``, a line strip through the camera centres in shooting order;
- ``/tf`` (``foxglove.FrameTransforms``): ``base -> camera_optical`` at each view's timestamp
  (the camera moving along its tour on playback).

The scene entities are stamped at the first view's time with no lifetime, so they stay visible
during the whole playback. The MCAP metadata record ``armstereo`` holds the fusion report's
scalar keys. The triangle list is encoded straight into protobuf wire format with numpy (a
mesh has ~10^5 vertices; building one protobuf object per vertex takes seconds).
"""

from __future__ import annotations

import io
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from foxglove_schemas_protobuf.Color_pb2 import Color
from foxglove_schemas_protobuf.FrameTransform_pb2 import FrameTransform
from foxglove_schemas_protobuf.FrameTransforms_pb2 import FrameTransforms
from foxglove_schemas_protobuf.LinePrimitive_pb2 import LinePrimitive
from foxglove_schemas_protobuf.PackedElementField_pb2 import PackedElementField
from foxglove_schemas_protobuf.Point3_pb2 import Point3
from foxglove_schemas_protobuf.PointCloud_pb2 import PointCloud
from foxglove_schemas_protobuf.Pose_pb2 import Pose
from foxglove_schemas_protobuf.Quaternion_pb2 import Quaternion
from foxglove_schemas_protobuf.SceneEntity_pb2 import SceneEntity
from foxglove_schemas_protobuf.SceneUpdate_pb2 import SceneUpdate
from foxglove_schemas_protobuf.TextPrimitive_pb2 import TextPrimitive
from foxglove_schemas_protobuf.TriangleListPrimitive_pb2 import TriangleListPrimitive
from foxglove_schemas_protobuf.Vector3_pb2 import Vector3
from google.protobuf.timestamp_pb2 import Timestamp
from mcap.writer import CompressionType
from mcap.writer import Writer as McapWriter
from mcap_protobuf.schema import register_schema

from armstereo import __version__
from armstereo.errors import RecordingError
from armstereo.fusion.mesh import Mesh
from armstereo.io.files import write_bytes_atomic
from armstereo.recording.messages import POINT_DTYPE, POINT_STRIDE
from armstereo.transforms import quaternion_xyzw

TOPIC_MESH = "/fusion/mesh"
TOPIC_POINTS = "/fusion/points"
TOPIC_VIEWS = "/fusion/views"
TOPIC_TF = "/tf"
FRAME_BASE = "base"
FRAME_CAMERA = "camera_optical"
METADATA_NAME = "armstereo"
FRUSTUM_DEPTH_M = 0.08  # how far the drawn frustums reach
FRUSTUM_RGBA = (0.1, 0.6, 1.0, 1.0)
TOUR_RGBA = (1.0, 0.55, 0.0, 1.0)
LINE_THICKNESS_PX = 2.0
LABEL_SIZE_PX = 14.0

# Protobuf wire format of the repeated fields of foxglove.TriangleListPrimitive (field numbers
# from its schema: points = 2 (Point3: x, y, z doubles 1..3), colors = 4 (Color: r, g, b, a
# doubles 1..4), indices = 5 (packed fixed32)).
_POINT_FIELD, _COLOR_FIELD, _INDEX_FIELD = 2, 4, 5
_WIRE_LEN, _WIRE_FIXED64 = 2, 1


@dataclass(frozen=True)
class ViewPose:
    """A recorded view for drawing: its number, its pair, camera pose (base), K and image
    size (width, height), time (ns)."""

    view: int
    pair: int
    T_base_camera: np.ndarray
    K: np.ndarray
    size: tuple[int, int]
    timestamp_ns: int


def _tag(field: int, wire: int) -> int:
    return (field << 3) | wire


def _varint(n: int) -> bytes:
    out = bytearray()
    while True:
        byte = n & 0x7F
        n >>= 7
        if n:
            out.append(byte | 0x80)
        else:
            out.append(byte)
            return bytes(out)


def _repeated_doubles(field: int, values: np.ndarray) -> bytes:
    """A repeated sub-message field whose messages hold doubles in fields 1..k (all present)."""
    n, k = values.shape
    size = k * 9  # per double: tag byte + 8 bytes
    dtype = np.dtype([("tag", "u1"), ("len", "u1")]
                     + [item for i in range(k) for item in ((f"t{i}", "u1"), (f"v{i}", "<f8"))])
    rec = np.empty(n, dtype=dtype)
    rec["tag"] = _tag(field, _WIRE_LEN)
    rec["len"] = size  # < 128: one varint byte
    for i in range(k):
        rec[f"t{i}"] = _tag(i + 1, _WIRE_FIXED64)
        rec[f"v{i}"] = values[:, i]
    return rec.tobytes()


def triangle_list(mesh: Mesh) -> TriangleListPrimitive:
    """The mesh as one ``TriangleListPrimitive`` (base frame, identity pose, vertex colours)."""
    head = TriangleListPrimitive(pose=_identity_pose(), color=Color(r=0.7, g=0.7, b=0.7, a=1.0))
    rgba = np.ones((len(mesh.vertices), 4))
    rgba[:, :3] = mesh.colors[:, ::-1] / 255.0  # BGR -> RGB
    indices = np.ascontiguousarray(mesh.faces.reshape(-1), dtype="<u4").tobytes()
    data = (head.SerializeToString()
            + _repeated_doubles(_POINT_FIELD, mesh.vertices.astype(np.float64))
            + _repeated_doubles(_COLOR_FIELD, rgba)
            + (bytes([_tag(_INDEX_FIELD, _WIRE_LEN)]) + _varint(len(indices)) + indices
               if indices else b""))
    return TriangleListPrimitive.FromString(data)


def _identity_pose() -> Pose:
    return Pose(position=Vector3(), orientation=Quaternion(w=1.0))


def _pose(T: np.ndarray) -> Pose:
    x, y, z, w = quaternion_xyzw(T[:3, :3])
    return Pose(position=Vector3(x=T[0, 3], y=T[1, 3], z=T[2, 3]),
                orientation=Quaternion(x=x, y=y, z=z, w=w))


def _stamp(t_ns: int) -> Timestamp:
    ts = Timestamp()
    ts.FromNanoseconds(int(t_ns))
    return ts


def _frustum(view: ViewPose) -> LinePrimitive:
    """Lines from the optical centre to the image corners at FRUSTUM_DEPTH_M, and the far
    rectangle; in the camera frame (the primitive's pose places it)."""
    w, h = view.size
    K = view.K
    corners = []
    for u, v in ((-0.5, -0.5), (w - 0.5, -0.5), (w - 0.5, h - 0.5), (-0.5, h - 0.5)):
        x, y = (u - K[0, 2]) / K[0, 0], (v - K[1, 2]) / K[1, 1]
        corners.append(Point3(x=x * FRUSTUM_DEPTH_M, y=y * FRUSTUM_DEPTH_M, z=FRUSTUM_DEPTH_M))
    points = [Point3()] + corners
    indices = [0, 1, 0, 2, 0, 3, 0, 4, 1, 2, 2, 3, 3, 4, 4, 1]
    r, g, b, a = FRUSTUM_RGBA
    return LinePrimitive(type=LinePrimitive.LINE_LIST, pose=_pose(view.T_base_camera),
                         thickness=LINE_THICKNESS_PX, scale_invariant=True, points=points,
                         color=Color(r=r, g=g, b=b, a=a), indices=indices)


def _views_update(views: Sequence[ViewPose], t_ns: int) -> SceneUpdate:
    entities = []
    for view in views:
        label = TextPrimitive(pose=_pose(view.T_base_camera), billboard=True,
                              font_size=LABEL_SIZE_PX, scale_invariant=True,
                              color=Color(r=1.0, g=1.0, b=1.0, a=1.0),
                              text=f"view {view.view} (pair {view.pair})")
        entities.append(SceneEntity(timestamp=_stamp(t_ns), frame_id=FRAME_BASE,
                                    id=f"view_{view.view}", lines=[_frustum(view)],
                                    texts=[label]))
    r, g, b, a = TOUR_RGBA
    tour = LinePrimitive(type=LinePrimitive.LINE_STRIP, pose=_identity_pose(),
                         thickness=LINE_THICKNESS_PX, scale_invariant=True,
                         points=[Point3(x=v.T_base_camera[0, 3], y=v.T_base_camera[1, 3],
                                        z=v.T_base_camera[2, 3]) for v in views],
                         color=Color(r=r, g=g, b=b, a=a))
    entities.append(SceneEntity(timestamp=_stamp(t_ns), frame_id=FRAME_BASE, id="tour",
                                lines=[tour]))
    return SceneUpdate(entities=entities)


def _cloud(points: np.ndarray, colors_bgr: np.ndarray, t_ns: int) -> PointCloud:
    packed = np.empty(len(points), dtype=POINT_DTYPE)
    for axis, name in enumerate("xyz"):
        packed[name] = points[:, axis]
    packed["red"], packed["green"], packed["blue"] = (colors_bgr[:, 2], colors_bgr[:, 1],
                                                      colors_bgr[:, 0])
    packed["alpha"] = 255
    f32, u8 = PackedElementField.FLOAT32, PackedElementField.UINT8
    fields = [PackedElementField(name=n, offset=POINT_DTYPE.fields[n][1],
                                 type=f32 if n in "xyz" else u8) for n in POINT_DTYPE.names]
    return PointCloud(timestamp=_stamp(t_ns), frame_id=FRAME_BASE, pose=_identity_pose(),
                      point_stride=POINT_STRIDE, fields=fields, data=packed.tobytes())


def _camera_tf(view: ViewPose) -> FrameTransforms:
    T = view.T_base_camera
    x, y, z, w = quaternion_xyzw(T[:3, :3])
    return FrameTransforms(transforms=[FrameTransform(
        timestamp=_stamp(view.timestamp_ns), parent_frame_id=FRAME_BASE,
        child_frame_id=FRAME_CAMERA, translation=Vector3(x=T[0, 3], y=T[1, 3], z=T[2, 3]),
        rotation=Quaternion(x=x, y=y, z=z, w=w))])


def write_fusion_mcap(path: str | Path, mesh: Mesh, points: np.ndarray, colors_bgr: np.ndarray,
                      views: Sequence[ViewPose], metadata: Mapping[str, str]) -> Path:
    """Write the scan's MCAP atomically (see the module docstring); returns the path."""
    views = sorted(views, key=lambda v: v.timestamp_ns)
    t0 = views[0].timestamp_ns if views else 0
    meta = {"armstereo_version": __version__, "kind": "fusion", **dict(metadata)}
    buf = io.BytesIO()
    writer = McapWriter(buf, compression=CompressionType.ZSTD)
    writer.start(profile="", library=f"armstereo {__version__}")
    writer.add_metadata(METADATA_NAME, {str(k): str(v) for k, v in meta.items()})
    channels: dict[str, int] = {}

    def put(topic: str, msg, t_ns: int) -> None:
        if topic not in channels:
            schema = register_schema(writer, type(msg))
            channels[topic] = writer.register_channel(topic, "protobuf", schema)
        writer.add_message(channels[topic], log_time=t_ns, publish_time=t_ns,
                           data=msg.SerializeToString(), sequence=0)

    mesh_entity = SceneEntity(timestamp=_stamp(t0), frame_id=FRAME_BASE, id="mesh",
                              triangles=[triangle_list(mesh)])
    put(TOPIC_MESH, SceneUpdate(entities=[mesh_entity]), t0)
    put(TOPIC_POINTS, _cloud(np.asarray(points, np.float32).reshape(-1, 3),
                             np.asarray(colors_bgr, np.uint8).reshape(-1, 3), t0), t0)
    put(TOPIC_VIEWS, _views_update(views, t0), t0)
    for view in views:
        put(TOPIC_TF, _camera_tf(view), view.timestamp_ns)
    writer.finish()
    try:
        return write_bytes_atomic(path, buf.getvalue())
    except OSError as err:
        raise RecordingError(f"cannot write {path}: {err.strerror or err}") from None
