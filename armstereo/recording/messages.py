"""The Foxglove messages a recording holds, built from checked values: time stamps, the packed
point cloud layout, depth images and the ``/tf`` pair of transforms (``base`` -> ``tool0`` ->
``camera_optical``). Pure functions; the writer (:mod:`~armstereo.recording.writer`) sends them.
Every check raises :class:`~armstereo.errors.RecordingError` naming the value."""

from __future__ import annotations

import numpy as np
from foxglove_schemas_protobuf.FrameTransform_pb2 import FrameTransform
from foxglove_schemas_protobuf.FrameTransforms_pb2 import FrameTransforms
from foxglove_schemas_protobuf.PackedElementField_pb2 import PackedElementField
from foxglove_schemas_protobuf.Quaternion_pb2 import Quaternion
from foxglove_schemas_protobuf.RawImage_pb2 import RawImage
from foxglove_schemas_protobuf.Vector3_pb2 import Vector3
from google.protobuf.timestamp_pb2 import Timestamp

from armstereo.errors import RecordingError
from armstereo.recording import schemas as S
from armstereo.transforms import as_rigid, quaternion_xyzw

POINT_STRIDE = 16  # x, y, z float32 + r, g, b, a uint8
POINT_DTYPE = np.dtype({"names": ["x", "y", "z", "red", "green", "blue", "alpha"],
                        "formats": ["<f4", "<f4", "<f4", "u1", "u1", "u1", "u1"],
                        "offsets": [0, 4, 8, 12, 13, 14, 15], "itemsize": POINT_STRIDE})


def point_fields() -> list[PackedElementField]:
    f32, u8 = PackedElementField.FLOAT32, PackedElementField.UINT8
    return [PackedElementField(name=name, offset=POINT_DTYPE.fields[name][1],
                               type=f32 if name in "xyz" else u8)
            for name in POINT_DTYPE.names]


def depth_message(depth: np.ndarray, t_ns: int, frame_id: str) -> RawImage:
    d = np.asarray(depth)
    if d.ndim != 2 or d.dtype.kind != "f":
        raise RecordingError(f"depth must be a float HxW array, got {d.dtype} {d.shape}")
    d = np.ascontiguousarray(d, dtype="<f4")
    h, w = d.shape
    return RawImage(timestamp=stamp(t_ns), frame_id=frame_id, width=w, height=h,
                    encoding=S.DEPTH_ENCODING, step=4 * w, data=d.tobytes())


def frames_message(T_base_flange: np.ndarray, T_flange_camera: np.ndarray,
                    t_ns: int) -> FrameTransforms:
    return FrameTransforms(transforms=[
        transform("T_base_flange", T_base_flange, S.FRAME_BASE, S.FRAME_FLANGE, t_ns),
        transform("T_flange_camera", T_flange_camera, S.FRAME_FLANGE, S.FRAME_CAMERA, t_ns),
    ])


def transform(name: str, T: np.ndarray, parent: str, child: str, t_ns: int) -> FrameTransform:
    """FrameTransform for the pose of ``child`` in ``parent`` (``T_parent_child``)."""
    T = as_rigid(T, name, error=RecordingError)
    x, y, z, w = quaternion_xyzw(T[:3, :3])
    tx, ty, tz = T[:3, 3]
    return FrameTransform(timestamp=stamp(t_ns), parent_frame_id=parent, child_frame_id=child,
                          translation=Vector3(x=tx, y=ty, z=tz),
                          rotation=Quaternion(x=x, y=y, z=z, w=w))


def stamp(t_ns: int) -> Timestamp:
    ts = Timestamp()
    ts.FromNanoseconds(t_ns)
    return ts


def check_time(t_ns) -> int:
    if isinstance(t_ns, bool) or not isinstance(t_ns, (int, np.integer)):
        raise RecordingError(f"timestamps are integer nanoseconds, got {type(t_ns).__name__}")
    if not 0 <= int(t_ns) < 2**63:
        raise RecordingError(f"timestamp {t_ns} ns is outside 0 .. 2^63")
    return int(t_ns)


def check_index(name: str, value) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 0:
        raise RecordingError(f"{name} number must be an integer >= 0, got {value!r}")
    return int(value)


def check_vector(name: str, values) -> np.ndarray:
    v = np.asarray(values, dtype=float).reshape(-1)
    if not np.all(np.isfinite(v)):
        raise RecordingError(f"{name} must be finite, got {v}")
    return v


def check_number(name: str, value) -> float:
    x = float(value)
    if not np.isfinite(x):
        raise RecordingError(f"{name} must be finite, got {x}")
    return x
