"""``visualization_msgs/msg/Marker`` and ``MarkerArray`` encoded straight to CDR with numpy.

A fused mesh is one TRIANGLE_LIST marker of ~10^5..10^6 points; building one rosbags
``Point`` object per vertex and serializing them costs seconds (about 8 s for 600 000 points,
docs/ros2.md), writing the arrays as CDR bytes costs milliseconds. The layout is the one every
ROS 2 middleware reads: XCDR1 little endian (encapsulation ``00 01 00 00``), each primitive
aligned to its size from the start of the payload, strings as uint32 length (with the NUL),
bytes and NUL, sequences as uint32 count then the elements. Field order and types are
visualization_msgs/msg/Marker's (identical in Humble and Jazzy); the tests decode our bytes
with both rosbags and mcap-ros2-support and compare with rosbags' own serialization.
"""

from __future__ import annotations

import struct
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from armstereo.transforms import quaternion_xyzw

# Marker.type and Marker.action constants (the message's own).
CUBE, SPHERE, LINE_STRIP, LINE_LIST, CUBE_LIST = 1, 2, 4, 5, 6
TEXT_VIEW_FACING, TRIANGLE_LIST = 9, 11
ADD = 0
_ENCAPSULATION = b"\x00\x01\x00\x00"  # CDR, little endian


@dataclass(frozen=True, eq=False)
class MarkerSpec:
    """One marker: type, pose of its frame (4x4 in ``frame_id``, metres), scale (m), RGBA
    colour (0..1), per-point positions (N, 3) and RGBA colours (N, 4) for list types, text."""

    ns: str
    id: int
    type: int
    frame_id: str
    stamp_ns: int
    pose: np.ndarray = field(default_factory=lambda: np.eye(4))
    scale: tuple[float, float, float] = (1.0, 1.0, 1.0)
    color: tuple[float, float, float, float] = (1.0, 1.0, 1.0, 1.0)
    points: np.ndarray | None = None
    colors: np.ndarray | None = None
    text: str = ""
    frame_locked: bool = False
    lifetime_ns: int = 0


class _Cdr:
    """Append-only CDR writer; offsets count from the start of the payload."""

    def __init__(self) -> None:
        self.parts: list[bytes] = []
        self.size = 0

    def _put(self, data: bytes) -> None:
        self.parts.append(data)
        self.size += len(data)

    def align(self, n: int) -> None:
        pad = -self.size % n
        if pad:
            self._put(b"\x00" * pad)

    def pack(self, fmt: str, *values, align: int) -> None:
        self.align(align)
        self._put(struct.pack("<" + fmt, *values))

    def string(self, text: str) -> None:
        data = text.encode()
        self.pack("I", len(data) + 1, align=4)
        self._put(data + b"\x00")

    def array(self, values: np.ndarray, dtype: str, align: int) -> None:
        """A sequence of fixed-size elements (rows of ``values``), as one numpy block."""
        a = np.ascontiguousarray(values, dtype=dtype)
        self.pack("I", len(a), align=4)
        if len(a):
            self.align(align)
            self._put(a.tobytes())

    def time(self, t_ns: int) -> None:
        sec, nsec = divmod(int(t_ns), 1_000_000_000)
        self.pack("iI", sec, nsec, align=4)

    def bytes_(self) -> bytes:
        return _ENCAPSULATION + b"".join(self.parts)


def _marker(w: _Cdr, m: MarkerSpec) -> None:
    w.time(m.stamp_ns)
    w.string(m.frame_id)
    w.string(m.ns)
    w.pack("iii", int(m.id), int(m.type), ADD, align=4)
    T = np.asarray(m.pose, dtype=float)
    qx, qy, qz, qw = quaternion_xyzw(T[:3, :3])
    w.pack("7d", *T[:3, 3], qx, qy, qz, qw, align=8)
    w.pack("3d", *m.scale, align=8)
    w.pack("4f", *m.color, align=4)
    w.time(m.lifetime_ns)  # builtin_interfaces/Duration: int32 sec, uint32 nanosec
    w.pack("?", bool(m.frame_locked), align=1)
    pts = np.zeros((0, 3)) if m.points is None else np.asarray(m.points).reshape(-1, 3)
    cols = np.zeros((0, 4)) if m.colors is None else np.asarray(m.colors).reshape(-1, 4)
    w.array(pts, "<f8", 8)
    w.array(cols, "<f4", 4)
    w.string("")  # texture_resource
    w.time(0)  # texture: sensor_msgs/CompressedImage (header, format, data), empty
    w.string("")
    w.string("")
    w.array(np.zeros(0, np.uint8), "u1", 1)
    w.array(np.zeros((0, 2)), "<f4", 4)  # uv_coordinates
    w.string(m.text)
    w.string("")  # mesh_resource
    w.string("")  # mesh_file: filename, data
    w.array(np.zeros(0, np.uint8), "u1", 1)
    w.pack("?", False, align=1)  # mesh_use_embedded_materials


def encode_marker(m: MarkerSpec) -> bytes:
    """The CDR bytes of one ``visualization_msgs/msg/Marker``."""
    w = _Cdr()
    _marker(w, m)
    return w.bytes_()


def encode_marker_array(markers: Sequence[MarkerSpec]) -> bytes:
    """The CDR bytes of a ``visualization_msgs/msg/MarkerArray``."""
    w = _Cdr()
    w.pack("I", len(markers), align=4)
    for m in markers:
        _marker(w, m)
    return w.bytes_()
