"""Binary little-endian PLY point clouds (xyz float32 + red green blue uchar).

The header is the plain form Open3D, MeshLab and CloudCompare read::

    ply
    format binary_little_endian 1.0
    comment armstereo point cloud, frame base, metres
    element vertex N
    property float x
    property float y
    property float z
    property uchar red
    property uchar green
    property uchar blue
    end_header

Colours are passed and returned in the project's BGR order and stored as RGB in the file.
Writes are atomic (temporary file + rename), so a reader never sees half a cloud.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from armstereo.errors import StereoError
from armstereo.io.files import write_bytes_atomic

VERTEX_DTYPE = np.dtype([("x", "<f4"), ("y", "<f4"), ("z", "<f4"),
                         ("red", "u1"), ("green", "u1"), ("blue", "u1")])
_PLY_TYPES = {"char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1", "short": "<i2",
              "int16": "<i2", "ushort": "<u2", "uint16": "<u2", "int": "<i4", "int32": "<i4",
              "uint": "<u4", "uint32": "<u4", "float": "<f4", "float32": "<f4",
              "double": "<f8", "float64": "<f8"}


@dataclass(frozen=True)
class PlyCloud:
    """Points (N,3) float32, colours (N,3) uint8 BGR (None if the file has none), comments."""

    points: np.ndarray
    colors_bgr: np.ndarray | None
    comments: tuple[str, ...]


def encode_ply(points: np.ndarray, colors_bgr: np.ndarray, *, comment: str = "") -> bytes:
    """The bytes of a binary PLY of ``points`` (N,3, metres) coloured by ``colors_bgr`` (N,3)."""
    points = np.asarray(points)
    colors_bgr = np.asarray(colors_bgr)
    if points.ndim != 2 or points.shape[1] != 3:
        raise StereoError(f"points must be an (N, 3) array, got shape {points.shape}")
    if colors_bgr.shape != points.shape or colors_bgr.dtype != np.uint8:
        raise StereoError(f"colors must be (N, 3) uint8 like the points {points.shape}, got "
                          f"{colors_bgr.dtype} {colors_bgr.shape}")
    if "\n" in comment:
        raise StereoError("a PLY comment must be one line")
    vertices = np.empty(len(points), dtype=VERTEX_DTYPE)
    for i, axis in enumerate("xyz"):
        vertices[axis] = points[:, i]
    vertices["red"], vertices["green"], vertices["blue"] = (
        colors_bgr[:, 2], colors_bgr[:, 1], colors_bgr[:, 0])
    header = ["ply", "format binary_little_endian 1.0"]
    header += [f"comment {comment}"] if comment else []
    header += [f"element vertex {len(points)}"]
    header += [f"property float {a}" for a in "xyz"]
    header += [f"property uchar {c}" for c in ("red", "green", "blue")]
    header += ["end_header"]
    return ("\n".join(header) + "\n").encode("ascii") + vertices.tobytes()


def write_ply(path: str | Path, points: np.ndarray, colors_bgr: np.ndarray, *,
              comment: str = "") -> Path:
    """Write a binary PLY atomically; returns the path."""
    return write_bytes_atomic(path, encode_ply(points, colors_bgr, comment=comment))


def read_ply(path: str | Path) -> PlyCloud:
    """Read a binary little-endian PLY with one ``vertex`` element of scalar properties.

    Enough for round-trip tests and for clouds from other tools that use that layout; raises
    StereoError for anything else (ASCII, big-endian, list properties, several elements).
    """
    data = Path(path).read_bytes()
    end = data.find(b"end_header\n")
    if not data.startswith(b"ply\n") or end < 0:
        raise StereoError(f"{path}: not a PLY file (no 'ply' magic or no end_header)")
    lines = data[:end].decode("ascii").splitlines()
    if "format binary_little_endian 1.0" not in lines:
        raise StereoError(f"{path}: only binary_little_endian 1.0 PLY is supported")
    comments, count, fields = [], None, []
    for line in lines[1:]:
        words = line.split()
        if words[0] == "comment":
            comments.append(line[len("comment "):])
        elif words[0] == "element":
            if count is not None or words[1] != "vertex":
                raise StereoError(f"{path}: only a single 'vertex' element is supported")
            count = int(words[2])
        elif words[0] == "property":
            if words[1] == "list" or words[1] not in _PLY_TYPES:
                raise StereoError(f"{path}: unsupported property {line!r}")
            fields.append((words[2], _PLY_TYPES[words[1]]))
    dtype = np.dtype(fields)
    body = data[end + len(b"end_header\n"):]
    if count is None or len(body) < count * dtype.itemsize:
        raise StereoError(f"{path}: truncated: header promises {count} vertices of "
                          f"{dtype.itemsize} bytes, body has {len(body)} bytes")
    v = np.frombuffer(body, dtype=dtype, count=count)
    points = np.stack([v["x"], v["y"], v["z"]], axis=1).astype(np.float32)
    names = dtype.names or ()
    colors = (np.stack([v["blue"], v["green"], v["red"]], axis=1).astype(np.uint8)
              if {"red", "green", "blue"} <= set(names) else None)
    return PlyCloud(points, colors, tuple(comments))
