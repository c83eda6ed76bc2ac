"""armstereo data as ROS 2 messages (rosbags message objects of one distribution's store).

Frames and units are ROS's and armstereo's alike: metres, radians, integer-nanosecond stamps,
the camera's optical frame is OpenCV's (x right, y down, z forward, REP 103's ``_optical``
frames). Images are ``bgr8`` (colour) or ``mono8`` (grey) as OpenCV holds them.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from armstereo.camera_model import Intrinsics
from armstereo.errors import OutputError
from armstereo.ros2 import types as R
from armstereo.transforms import as_rigid, quaternion_xyzw

# ROS's names for OpenCV's distortion vectors (sensor_msgs/distortion_models.hpp).
PLUMB_BOB = "plumb_bob"  # k1, k2, p1, p2, k3
RATIONAL_POLYNOMIAL = "rational_polynomial"  # k1, k2, p1, p2, k3, k4, k5, k6
DISTORTION_MODELS = (PLUMB_BOB, RATIONAL_POLYNOMIAL)
# Packed colour of a PointCloud2, as PCL and rviz read it: one FLOAT32 field "rgb" whose four
# bytes are blue, green, red and 0 (little endian: 0x00RRGGBB).
CLOUD_DTYPE = np.dtype({"names": ["x", "y", "z", "b", "g", "r", "a"],
                        "formats": ["<f4", "<f4", "<f4", "u1", "u1", "u1", "u1"],
                        "offsets": [0, 4, 8, 12, 13, 14, 15], "itemsize": 16})


def image(store, img: np.ndarray, t_ns: int, frame_id: str):
    """``sensor_msgs/msg/Image`` of a uint8 BGR (``bgr8``) or grey (``mono8``) image."""
    a = np.ascontiguousarray(img)
    if a.ndim == 3 and a.shape[2] == 1:
        a = a[:, :, 0]
    if a.dtype != np.uint8 or not (a.ndim == 2 or (a.ndim == 3 and a.shape[2] == 3)):
        raise OutputError(f"image must be uint8 HxW or HxWx3, got {a.dtype} {a.shape}")
    h, w = a.shape[:2]
    channels = 1 if a.ndim == 2 else 3
    return R.msg_class(store, R.IMAGE)(
        header=R.header(store, t_ns, frame_id), height=h, width=w,
        encoding="mono8" if channels == 1 else "bgr8", is_bigendian=0, step=w * channels,
        data=a.reshape(-1))


def float_image(store, depth: np.ndarray, t_ns: int, frame_id: str):
    """``sensor_msgs/msg/Image`` ``32FC1`` (float32 metres, NaN = none: REP 118's depth)."""
    d = np.ascontiguousarray(depth, dtype="<f4")
    h, w = d.shape
    return R.msg_class(store, R.IMAGE)(
        header=R.header(store, t_ns, frame_id), height=h, width=w, encoding="32FC1",
        is_bigendian=0, step=4 * w, data=np.frombuffer(d.tobytes(), dtype=np.uint8))


def compressed_image(store, data: bytes, fmt: str, grey: bool, t_ns: int, frame_id: str):
    """``sensor_msgs/msg/CompressedImage`` holding PNG or JPEG bytes as they are.

    ``format`` is written as compressed_image_transport writes it (``"bgr8; png compressed
    bgr8"``), so image_transport's ``compressed`` subscribers (rviz) decode it.
    """
    enc = "mono8" if grey else "bgr8"
    return R.msg_class(store, R.COMPRESSED_IMAGE)(
        header=R.header(store, t_ns, frame_id), format=f"{enc}; {fmt} compressed {enc}",
        data=np.frombuffer(bytes(data), dtype=np.uint8))


def distortion(dist: np.ndarray) -> tuple[str, np.ndarray]:
    """ROS's (distortion_model, D) for OpenCV coefficients; OutputError for models ROS's
    CameraInfo cannot name (non-zero thin-prism or tilt terms)."""
    d = np.asarray(dist, dtype=float).reshape(-1)
    if d.size == 4:
        d = np.append(d, 0.0)
    if d.size > 8:
        if np.any(d[8:] != 0):
            raise OutputError(f"the camera's {d.size}-term distortion has thin-prism or tilt "
                              "terms, which sensor_msgs/CameraInfo cannot carry")
        d = d[:8]
    return (PLUMB_BOB if d.size == 5 else RATIONAL_POLYNOMIAL), d


def camera_info(store, intr: Intrinsics, t_ns: int, frame_id: str):
    """``sensor_msgs/msg/CameraInfo``: K, D (OpenCV order), R = I, P = [K | 0]."""
    model, d = distortion(intr.dist)
    K = np.asarray(intr.K, dtype=float)
    roi = R.msg_class(store, "sensor_msgs/msg/RegionOfInterest")(
        x_offset=0, y_offset=0, height=0, width=0, do_rectify=False)
    return R.msg_class(store, R.CAMERA_INFO)(
        header=R.header(store, t_ns, frame_id), height=int(intr.height), width=int(intr.width),
        distortion_model=model, d=d.astype(np.float64), k=K.reshape(-1).copy(),
        r=np.eye(3).reshape(-1), p=np.hstack([K, np.zeros((3, 1))]).reshape(-1),
        binning_x=0, binning_y=0, roi=roi)


def transform(store, T: np.ndarray, parent: str, child: str, t_ns: int):
    """``geometry_msgs/msg/TransformStamped``: the pose of ``child`` in ``parent``
    (``T_parent_child``, metres, unit quaternion x, y, z, w)."""
    T = as_rigid(T, f"{parent}->{child}", error=OutputError)
    x, y, z, w = (float(v) for v in quaternion_xyzw(T[:3, :3]))
    tx, ty, tz = (float(v) for v in T[:3, 3])
    types = store.types
    tf = types["geometry_msgs/msg/Transform"](
        translation=types["geometry_msgs/msg/Vector3"](x=tx, y=ty, z=tz),
        rotation=types["geometry_msgs/msg/Quaternion"](x=x, y=y, z=z, w=w))
    return types["geometry_msgs/msg/TransformStamped"](
        header=R.header(store, t_ns, parent), child_frame_id=str(child), transform=tf)


def tf_message(store, transforms: Sequence):
    """``tf2_msgs/msg/TFMessage`` of TransformStamped messages."""
    return R.msg_class(store, R.TF_MESSAGE)(transforms=list(transforms))


def joint_state(store, names: Sequence[str], positions: np.ndarray, t_ns: int):
    """``sensor_msgs/msg/JointState`` with positions only (rad); frame id empty, as the UR
    driver's joint_state_broadcaster publishes it."""
    q = np.asarray(positions, dtype=np.float64).reshape(-1)
    return R.msg_class(store, R.JOINT_STATE)(
        header=R.header(store, t_ns, ""), name=[str(n) for n in names], position=q,
        velocity=np.zeros(0), effort=np.zeros(0))


def point_cloud2(store, points: np.ndarray, colors_bgr: np.ndarray | None, t_ns: int,
                 frame_id: str):
    """``sensor_msgs/msg/PointCloud2``: one row of points, fields ``x y z`` FLOAT32 at 0, 4, 8
    and ``rgb`` FLOAT32 (packed 0x00RRGGBB) at 12; ``is_dense`` when every point is finite."""
    pts = np.asarray(points, dtype=float).reshape(-1, 3)
    packed = np.zeros(len(pts), dtype=CLOUD_DTYPE)
    for k, name in enumerate("xyz"):
        packed[name] = pts[:, k]
    if colors_bgr is not None:
        cols = np.asarray(colors_bgr, dtype=np.uint8).reshape(-1, 3)
        packed["b"], packed["g"], packed["r"] = cols[:, 0], cols[:, 1], cols[:, 2]
    field = store.types["sensor_msgs/msg/PointField"]
    f32 = field.FLOAT32
    fields = [field(name=n, offset=o, datatype=f32, count=1)
              for n, o in (("x", 0), ("y", 4), ("z", 8), ("rgb", 12))]
    return R.msg_class(store, R.POINT_CLOUD2)(
        header=R.header(store, t_ns, frame_id), height=1, width=len(pts), fields=fields,
        is_bigendian=False, point_step=CLOUD_DTYPE.itemsize,
        row_step=CLOUD_DTYPE.itemsize * len(pts),
        data=np.frombuffer(packed.tobytes(), dtype=np.uint8),
        is_dense=bool(np.all(np.isfinite(packed["x"]) & np.isfinite(packed["y"])
                             & np.isfinite(packed["z"]))))


def string(store, text: str):
    """``std_msgs/msg/String``."""
    return R.msg_class(store, R.STRING)(data=str(text))
