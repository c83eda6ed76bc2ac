"""Foxglove messages as what ROS 2 carries: point arrays and markers.

armstereo's outputs use Foxglove's schemas (``foxglove.PointCloud``, ``SceneUpdate``, ``Grid``,
``VoxelGrid``); ROS 2 has PointCloud2 and visualization markers instead. Everything here maps
into the message's ``frame_id`` (metres): a Foxglove pose on the message or primitive is
applied to the points (PointCloud2 has no pose) or becomes the marker's pose.
"""

from __future__ import annotations

import logging

import numpy as np
from foxglove_schemas_protobuf.LinePrimitive_pb2 import LinePrimitive
from foxglove_schemas_protobuf.PackedElementField_pb2 import PackedElementField

from armstereo.ros2 import markers as M
from armstereo.transforms import make_T, matrix_from_quaternion_xyzw, transform_points

log = logging.getLogger(__name__)

# A Foxglove line thickness or font size given in screen pixels (scale_invariant) has no size
# in the world; rviz markers need metres. One pixel is drawn as a millimetre.
METRES_PER_PIXEL = 0.001
_NUMERIC = {PackedElementField.UINT8: "u1", PackedElementField.INT8: "i1",
            PackedElementField.UINT16: "<u2", PackedElementField.INT16: "<i2",
            PackedElementField.UINT32: "<u4", PackedElementField.INT32: "<i4",
            PackedElementField.FLOAT32: "<f4", PackedElementField.FLOAT64: "<f8"}


def stamp_ns(ts) -> int:
    """Integer nanoseconds of a protobuf Timestamp."""
    return int(ts.seconds) * 1_000_000_000 + int(ts.nanos)


def pose_matrix(pose) -> np.ndarray:
    """4x4 of a foxglove Pose (an unset orientation is the identity)."""
    q = np.array([pose.orientation.x, pose.orientation.y, pose.orientation.z,
                  pose.orientation.w])
    R = np.eye(3) if not np.any(q) else matrix_from_quaternion_xyzw(q / np.linalg.norm(q))
    return make_T(R, [pose.position.x, pose.position.y, pose.position.z])


def _fields(fields, stride: int, data: bytes, rows: int | None = None) -> np.ndarray:
    """The packed records of ``data`` as a structured numpy array (one record per stride)."""
    known = [f for f in fields if f.type in _NUMERIC]
    dtype = np.dtype({"names": [f.name for f in known],
                      "formats": [_NUMERIC[f.type] for f in known],
                      "offsets": [f.offset for f in known], "itemsize": stride})
    n = len(data) // stride if rows is None else rows
    return np.frombuffer(data, dtype=dtype, count=n)


def _colors(rec: np.ndarray) -> np.ndarray | None:
    names = rec.dtype.names or ()
    if not {"red", "green", "blue"} <= set(names):
        return None
    return np.stack([rec["blue"], rec["green"], rec["red"]], axis=1).astype(np.uint8)


def point_cloud(msg) -> tuple[np.ndarray, np.ndarray | None]:
    """(points (N, 3) in the message's frame, BGR colours or None) of a foxglove.PointCloud."""
    if msg.point_stride < 1:
        raise ValueError("point cloud has no stride")
    rec = _fields(msg.fields, msg.point_stride, msg.data)
    if not {"x", "y", "z"} <= set(rec.dtype.names or ()):
        raise ValueError("point cloud lacks x, y, z fields")
    pts = np.stack([rec[n].astype(float) for n in "xyz"], axis=1)
    if msg.HasField("pose"):
        pts = transform_points(pose_matrix(msg.pose), pts)
    return pts, _colors(rec)


def grid_points(msg) -> tuple[np.ndarray, np.ndarray | None]:
    """Cell centres of a foxglove.Grid (height map) lifted by its ``elevation`` field, in the
    message's frame; cells with a NaN elevation or zero alpha are left out."""
    cols, stride = int(msg.column_count), int(msg.cell_stride)
    if cols < 1 or stride < 1 or msg.row_stride != cols * stride:
        raise ValueError("grid strides do not describe packed rows")
    rows = len(msg.data) // msg.row_stride
    rec = _fields(msg.fields, stride, msg.data, rows * cols)
    r, c = np.divmod(np.arange(rows * cols), cols)
    names = rec.dtype.names or ()
    z = rec["elevation"].astype(float) if "elevation" in names else np.zeros(len(rec))
    keep = np.isfinite(z) & ((rec["alpha"] > 0) if "alpha" in names else True)
    local = np.stack([(c + 0.5) * msg.cell_size.x, (r + 0.5) * msg.cell_size.y, z], axis=1)
    pts = transform_points(pose_matrix(msg.pose), local[keep])
    colors = _colors(rec)
    return pts, None if colors is None else colors[keep]


def voxel_marker(msg, t_ns: int, ns: str) -> M.MarkerSpec:
    """The occupied voxels of a foxglove.VoxelGrid as one CUBE_LIST marker: ``occupancy`` >= 50
    (nav_msgs' convention; armstereo writes 100) or, without that field, alpha > 0."""
    nx, ny, stride = int(msg.column_count), int(msg.row_count), int(msg.cell_stride)
    if nx < 1 or ny < 1 or stride < 1 or msg.row_stride != nx * stride \
            or msg.slice_stride != ny * nx * stride:
        raise ValueError("voxel grid strides do not describe packed slices")
    nz = len(msg.data) // msg.slice_stride
    rec = _fields(msg.fields, stride, msg.data, nx * ny * nz)
    names = rec.dtype.names or ()
    if "occupancy" in names:
        keep = rec["occupancy"].astype(int) >= 50
    else:
        keep = rec["alpha"] > 0 if "alpha" in names else np.ones(len(rec), bool)
    idx = np.flatnonzero(keep)
    s, rem = np.divmod(idx, nx * ny)
    y, x = np.divmod(rem, nx)
    size = np.array([msg.cell_size.x, msg.cell_size.y, msg.cell_size.z])
    centres = (np.stack([x, y, s], axis=1) + 0.5) * size
    rgba = np.ones((len(idx), 4), dtype=np.float32)
    for k, name in enumerate(("red", "green", "blue", "alpha")):
        if name in names:
            rgba[:, k] = rec[name][idx] / 255.0
    return M.MarkerSpec(ns, 0, M.CUBE_LIST, msg.frame_id, t_ns, pose=pose_matrix(msg.pose),
                        scale=tuple(float(v) for v in size), points=centres, colors=rgba)


def scene_markers(update, t_ns: int) -> list[M.MarkerSpec]:
    """One marker per primitive of a foxglove.SceneUpdate: namespace = entity id, id = the
    primitive's number in its entity. Arrows, cylinders and models (which armstereo does not
    write) are left out with a log line."""
    out: list[M.MarkerSpec] = []
    for e in update.entities:
        stamp = stamp_ns(e.timestamp) if e.HasField("timestamp") else t_ns
        base = {"ns": e.id, "frame_id": e.frame_id, "stamp_ns": stamp,
                "frame_locked": bool(e.frame_locked), "lifetime_ns": stamp_ns(e.lifetime)}
        specs = ([_triangles(t, base) for t in e.triangles] + [_lines(li, base) for li in e.lines]
                 + [_solid(c, M.CUBE, base) for c in e.cubes]
                 + [_solid(s, M.SPHERE, base) for s in e.spheres]
                 + [_text(t, base) for t in e.texts])
        out += [M.MarkerSpec(id=k, **spec) for k, spec in enumerate(specs)]
        skipped = len(e.arrows) + len(e.cylinders) + len(e.models)
        if skipped:
            log.info("entity %s: %d arrow/cylinder/model primitive(s) not exported", e.id,
                     skipped)
    return out


def _rgba(c) -> tuple[float, float, float, float]:
    return (float(c.r), float(c.g), float(c.b), float(c.a))


def _vertices(prim) -> tuple[np.ndarray, np.ndarray | None]:
    pts = np.array([[p.x, p.y, p.z] for p in prim.points], dtype=float).reshape(-1, 3)
    cols = (np.array([_rgba(c) for c in prim.colors], dtype=np.float32)
            if len(prim.colors) == len(prim.points) and len(prim.colors) else None)
    return pts, cols


def _indexed(prim, pts: np.ndarray, cols: np.ndarray | None):
    if not len(prim.indices):
        return pts, cols
    idx = np.asarray(prim.indices, dtype=np.int64)
    if idx.max(initial=-1) >= len(pts):
        raise ValueError("primitive index beyond its points")
    return pts[idx], None if cols is None else cols[idx]


def _triangles(prim, base: dict) -> dict:
    pts, cols = _indexed(prim, *_vertices(prim))
    n = len(pts) // 3 * 3
    return {**base, "type": M.TRIANGLE_LIST, "pose": pose_matrix(prim.pose),
            "color": _rgba(prim.color), "points": pts[:n],
            "colors": None if cols is None else cols[:n]}


def _lines(prim, base: dict) -> dict:
    pts, cols = _indexed(prim, *_vertices(prim))
    kind = M.LINE_LIST if prim.type == LinePrimitive.LINE_LIST else M.LINE_STRIP
    if prim.type == LinePrimitive.LINE_LOOP and len(pts):
        pts = np.vstack([pts, pts[:1]])
        cols = None if cols is None else np.vstack([cols, cols[:1]])
    width = prim.thickness * (METRES_PER_PIXEL if prim.scale_invariant else 1.0)
    return {**base, "type": kind, "pose": pose_matrix(prim.pose), "scale": (width, 0.0, 0.0),
            "color": _rgba(prim.color), "points": pts, "colors": cols}


def _solid(prim, kind: int, base: dict) -> dict:
    return {**base, "type": kind, "pose": pose_matrix(prim.pose),
            "scale": (prim.size.x, prim.size.y, prim.size.z), "color": _rgba(prim.color)}


def _text(prim, base: dict) -> dict:
    height = prim.font_size * (METRES_PER_PIXEL if prim.scale_invariant else 1.0)
    return {**base, "type": M.TEXT_VIEW_FACING, "pose": pose_matrix(prim.pose),
            "scale": (0.0, 0.0, height), "color": _rgba(prim.color), "text": prim.text}
