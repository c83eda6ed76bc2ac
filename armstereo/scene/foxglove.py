"""The analysis as an MCAP that Foxglove opens: cloud, objects, plane, height map, occupancy.

Topics (all in frame ``base``, one message each, at the cloud's time):

- ``/points`` (``foxglove.PointCloud``): the analysed cloud, as reconstruction writes it, so
  the file can be analysed again;
- ``/scene/objects`` (``foxglove.SceneUpdate``): entity ``plane`` (the support's convex hull
  as a line loop over a translucent fill) and one entity ``object/<id>`` per object: a cube
  (its gravity-aligned box, tinted with its mean colour), a sphere for sphere models, and a
  text label with its number, size and height; the numbers are also in the entity metadata;
- ``/scene/height_map`` (``foxglove.Grid``): in the plane, fields ``elevation`` (float32 m
  above the plane, NaN = unknown) and ``red green blue alpha`` (a colour scale over the
  heights; unknown cells transparent);
- ``/scene/occupancy`` (``foxglove.VoxelGrid``): fields ``occupancy`` (int8: -1 unknown,
  0 free, 100 occupied) and ``red green blue alpha`` (occupied opaque, unknown faint, free
  invisible).

The metadata record ``armstereo`` holds the source's metadata (robot, scene truth, ...) plus
``kind = scene_analysis`` and the whole ``scene.json`` under ``scene``.
"""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
from foxglove_schemas_protobuf.Color_pb2 import Color
from foxglove_schemas_protobuf.CubePrimitive_pb2 import CubePrimitive
from foxglove_schemas_protobuf.Grid_pb2 import Grid
from foxglove_schemas_protobuf.KeyValuePair_pb2 import KeyValuePair
from foxglove_schemas_protobuf.LinePrimitive_pb2 import LinePrimitive
from foxglove_schemas_protobuf.PackedElementField_pb2 import PackedElementField
from foxglove_schemas_protobuf.Point3_pb2 import Point3
from foxglove_schemas_protobuf.PointCloud_pb2 import PointCloud
from foxglove_schemas_protobuf.Pose_pb2 import Pose
from foxglove_schemas_protobuf.Quaternion_pb2 import Quaternion
from foxglove_schemas_protobuf.SceneEntity_pb2 import SceneEntity
from foxglove_schemas_protobuf.SceneUpdate_pb2 import SceneUpdate
from foxglove_schemas_protobuf.SpherePrimitive_pb2 import SpherePrimitive
from foxglove_schemas_protobuf.TextPrimitive_pb2 import TextPrimitive
from foxglove_schemas_protobuf.TriangleListPrimitive_pb2 import TriangleListPrimitive
from foxglove_schemas_protobuf.Vector2_pb2 import Vector2
from foxglove_schemas_protobuf.Vector3_pb2 import Vector3
from foxglove_schemas_protobuf.VoxelGrid_pb2 import VoxelGrid
from google.protobuf.timestamp_pb2 import Timestamp
from mcap.writer import CompressionType
from mcap.writer import Writer as McapWriter
from mcap_protobuf.schema import register_schema

from armstereo import __version__
from armstereo.errors import ConfigError
from armstereo.recording.schemas import (
    FORMAT_VERSION,
    FRAME_BASE,
    METADATA_NAME,
    PROTOBUF,
    TOPIC_POINTS,
)
from armstereo.scene.analysis import SceneAnalysis, SceneObject
from armstereo.scene.cloud import SceneCloud
from armstereo.scene.heightmap import OCCUPIED, UNKNOWN
from armstereo.transforms import quaternion_xyzw

TOPIC_OBJECTS = "/scene/objects"
TOPIC_HEIGHT_MAP = "/scene/height_map"
TOPIC_OCCUPANCY = "/scene/occupancy"
OBJECT_ALPHA = 0.55
PLANE_RGBA = (0.3, 0.6, 1.0, 0.15)
LABEL_FONT_PX = 14.0
LABEL_LIFT_M = 0.015  # labels float this far above the object's top
_F32, _U8, _I8 = PackedElementField.FLOAT32, PackedElementField.UINT8, PackedElementField.INT8
_POINT = np.dtype({"names": ["x", "y", "z", "red", "green", "blue", "alpha"],
                   "formats": ["<f4"] * 3 + ["u1"] * 4,
                   "offsets": [0, 4, 8, 12, 13, 14, 15], "itemsize": 16})
_CELL = np.dtype({"names": ["elevation", "red", "green", "blue", "alpha"],
                  "formats": ["<f4"] + ["u1"] * 4, "offsets": [0, 4, 5, 6, 7], "itemsize": 8})
_VOXEL = np.dtype({"names": ["occupancy", "red", "green", "blue", "alpha"],
                   "formats": ["i1"] + ["u1"] * 4, "offsets": [0, 1, 2, 3, 4], "itemsize": 5})


def write_scene_mcap(path: str | Path, analysis: SceneAnalysis, cloud: SceneCloud) -> Path:
    """Write the analysis MCAP (module doc); ConfigError if the file cannot be written."""
    path = Path(path)
    t_ns = int(cloud.timestamp_ns)
    meta = {k: v for k, v in cloud.metadata.items()
            if k not in ("format_version", "armstereo_version")}
    meta.update({"kind": "scene_analysis", "format_version": FORMAT_VERSION,
                 "armstereo_version": __version__,
                 "source": analysis.source, "scene": json.dumps(analysis.as_dict())})
    messages = [(TOPIC_POINTS, point_cloud_message(cloud, t_ns)),
                (TOPIC_OBJECTS, scene_update(analysis, t_ns)),
                (TOPIC_HEIGHT_MAP, height_map_grid(analysis, t_ns)),
                (TOPIC_OCCUPANCY, occupancy_voxels(analysis, t_ns))]
    try:
        with open(path, "wb") as f:
            writer = McapWriter(f, compression=CompressionType.ZSTD)
            writer.start(profile="", library=f"armstereo {__version__}")
            writer.add_metadata(METADATA_NAME, meta)
            schemas: dict[str, int] = {}
            for topic, msg in messages:
                name = msg.DESCRIPTOR.full_name
                if name not in schemas:
                    schemas[name] = register_schema(writer, type(msg))
                channel = writer.register_channel(topic=topic, message_encoding=PROTOBUF,
                                                  schema_id=schemas[name])
                writer.add_message(channel_id=channel, log_time=t_ns, publish_time=t_ns,
                                   data=msg.SerializeToString(), sequence=0)
            writer.finish()
    except OSError as err:
        raise ConfigError(f"cannot write {path}: {err.strerror}") from None
    return path


def _stamp(t_ns: int) -> Timestamp:
    ts = Timestamp()
    ts.FromNanoseconds(t_ns)
    return ts


def _pose(T: np.ndarray) -> Pose:
    x, y, z, w = quaternion_xyzw(T[:3, :3])
    return Pose(position=Vector3(x=T[0, 3], y=T[1, 3], z=T[2, 3]),
                orientation=Quaternion(x=x, y=y, z=z, w=w))


def _fields(dtype: np.dtype, types: dict[str, int]) -> list[PackedElementField]:
    return [PackedElementField(name=n, offset=dtype.fields[n][1], type=types[n])
            for n in dtype.names]


def point_cloud_message(cloud: SceneCloud, t_ns: int) -> PointCloud:
    """The analysed cloud as ``foxglove.PointCloud`` (float32 xyz + rgba, base frame)."""
    packed = np.zeros(len(cloud.points), dtype=_POINT)
    for k, name in enumerate("xyz"):
        packed[name] = cloud.points[:, k]
    if cloud.colors_bgr is not None:
        for k, name in enumerate(("blue", "green", "red")):
            packed[name] = cloud.colors_bgr[:, k]
    packed["alpha"] = 255
    types = {n: (_F32 if n in "xyz" else _U8) for n in _POINT.names}
    return PointCloud(timestamp=_stamp(t_ns), frame_id=FRAME_BASE, pose=_pose(np.eye(4)),
                      point_stride=_POINT.itemsize, fields=_fields(_POINT, types),
                      data=packed.tobytes())


def scene_update(analysis: SceneAnalysis, t_ns: int) -> SceneUpdate:
    """Plane entity and one entity per object (module doc)."""
    stamp = _stamp(t_ns)
    hull = analysis.plane.hull_base
    pts = [Point3(x=p[0], y=p[1], z=p[2]) for p in hull]
    tri = [i for k in range(1, len(hull) - 1) for i in (0, k, k + 1)]
    plane = SceneEntity(
        timestamp=stamp, frame_id=FRAME_BASE, id="plane", frame_locked=True,
        lines=[LinePrimitive(type=LinePrimitive.LINE_LOOP, pose=_pose(np.eye(4)), thickness=2,
                             scale_invariant=True, points=pts, color=Color(r=0.3, g=0.6, b=1,
                                                                           a=1))],
        triangles=[TriangleListPrimitive(pose=_pose(np.eye(4)), points=pts,
                                         color=Color(r=PLANE_RGBA[0], g=PLANE_RGBA[1],
                                                     b=PLANE_RGBA[2], a=PLANE_RGBA[3]),
                                         indices=tri)],
        metadata=[KeyValuePair(key="height_m", value=f"{analysis.plane.height_m:.5f}"),
                  KeyValuePair(key="rms_m", value=f"{analysis.plane.rms_m:.6f}")])
    entities = [plane] + [_object_entity(o, analysis, stamp) for o in analysis.objects]
    return SceneUpdate(entities=entities)


def object_label(o: SceneObject) -> str:
    """``#id LxWxH mm`` (the label in Foxglove and in the top-down picture)."""
    L, W, H = (v * 1000 for v in o.size_m)
    return f"#{o.id} {L:.0f}x{W:.0f}x{H:.0f} mm" + (" (partial)" if o.partial else "")


def _object_entity(o: SceneObject, analysis: SceneAnalysis, stamp: Timestamp) -> SceneEntity:
    T = analysis.plane.T_base_plane.copy()
    c, s = np.cos(np.radians(o.yaw_deg)), np.sin(np.radians(o.yaw_deg))
    # box axes: the length axis at the object's yaw, projected into the plane; z = normal
    n = T[:3, 2]
    x = np.array([c, s, 0.0]) - (np.array([c, s, 0.0]) @ n) * n
    x /= np.linalg.norm(x)
    box = np.eye(4)
    box[:3, 0], box[:3, 1], box[:3, 2], box[:3, 3] = x, np.cross(n, x), n, o.center_m
    rgb = (np.asarray(o.appearance.mean_rgb) / 255.0 if o.appearance is not None
           else np.array([0.8, 0.8, 0.8]))
    color = Color(r=rgb[0], g=rgb[1], b=rgb[2], a=OBJECT_ALPHA)
    L, W, H = o.size_m
    top = np.eye(4)
    top[:3, 3] = o.center_m + n * (H / 2 + LABEL_LIFT_M)
    entity = SceneEntity(
        timestamp=stamp, frame_id=FRAME_BASE, id=f"object/{o.id}", frame_locked=True,
        cubes=[CubePrimitive(pose=_pose(box), size=Vector3(x=L, y=W, z=H), color=color)],
        texts=[TextPrimitive(pose=_pose(top), billboard=True, font_size=LABEL_FONT_PX,
                             scale_invariant=True, color=Color(r=1, g=1, b=1, a=1),
                             text=object_label(o))],
        metadata=[KeyValuePair(key=k, value=str(v)) for k, v in
                  (("height_m", f"{o.height_m:.4f}"), ("size_m", _fmt(o.size_m)),
                   ("yaw_deg", f"{o.yaw_deg:.1f}"), ("points", o.points), ("model", o.model),
                   ("partial", str(o.partial).lower()))])
    if o.model == "sphere" and o.radius_m is not None:
        ball = np.eye(4)
        ball[:3, 3] = o.center_m + n * (H / 2 - o.radius_m)
        d = 2 * o.radius_m
        entity.spheres.append(SpherePrimitive(pose=_pose(ball), size=Vector3(x=d, y=d, z=d),
                                              color=color))
    return entity


def _fmt(v) -> str:
    return "[" + ", ".join(f"{x:.4f}" for x in v) + "]"


def height_map_grid(analysis: SceneAnalysis, t_ns: int) -> Grid:
    """The height map as ``foxglove.Grid`` lying in the plane (module doc)."""
    hm = analysis.height_map
    h = hm.heights
    rows, cols = h.shape
    cells = np.zeros((rows, cols), dtype=_CELL)
    cells["elevation"] = h
    rgba = height_colors(h)
    for k, name in enumerate(("red", "green", "blue", "alpha")):
        cells[name] = rgba[..., k]
    types = {"elevation": _F32, "red": _U8, "green": _U8, "blue": _U8, "alpha": _U8}
    return Grid(timestamp=_stamp(t_ns), frame_id=FRAME_BASE, pose=_pose(hm.T_base_grid),
                column_count=cols, cell_size=Vector2(x=hm.cell_m, y=hm.cell_m),
                row_stride=cols * _CELL.itemsize, cell_stride=_CELL.itemsize,
                fields=_fields(_CELL, types), data=cells.tobytes())


def height_colors(heights: np.ndarray) -> np.ndarray:
    """RGBA uint8 (rows, cols, 4): turbo over 0..max height, unknown transparent."""
    known = np.isfinite(heights)
    top = float(np.nanmax(heights)) if known.any() else 1.0
    v = np.clip(np.nan_to_num(heights, nan=0.0) / max(top, 1e-6), 0.0, 1.0)
    bgr = cv2.applyColorMap((v * 255).astype(np.uint8), cv2.COLORMAP_TURBO)
    rgba = np.zeros(heights.shape + (4,), dtype=np.uint8)
    rgba[..., :3] = bgr[..., ::-1]
    rgba[..., 3] = np.where(known, 255, 0)
    return rgba


def occupancy_voxels(analysis: SceneAnalysis, t_ns: int) -> VoxelGrid:
    """The occupancy grid as ``foxglove.VoxelGrid`` (module doc)."""
    occ = analysis.occupancy
    nz, ny, nx = occ.grid.shape
    vox = np.zeros(occ.grid.shape, dtype=_VOXEL)
    vox["occupancy"] = occ.grid
    occupied, unknown = occ.grid == OCCUPIED, occ.grid == UNKNOWN
    vox["red"] = np.where(occupied, 230, 128)
    vox["green"] = np.where(occupied, 80, 128)
    vox["blue"] = np.where(occupied, 40, 128)
    vox["alpha"] = np.where(occupied, 200, np.where(unknown, 25, 0))
    types = {"occupancy": _I8, "red": _U8, "green": _U8, "blue": _U8, "alpha": _U8}
    c = occ.cell_m
    return VoxelGrid(timestamp=_stamp(t_ns), frame_id=FRAME_BASE, pose=_pose(occ.T_base_grid),
                     row_count=ny, column_count=nx, cell_size=Vector3(x=c, y=c, z=c),
                     slice_stride=ny * nx * _VOXEL.itemsize, row_stride=nx * _VOXEL.itemsize,
                     cell_stride=_VOXEL.itemsize, fields=_fields(_VOXEL, types),
                     data=vox.tobytes())
