"""ROS 2 bags recorded the way a UR arm and a camera driver publish, built with
mcap-ros2-support (not rosbags, which the import reads with).

What is on the bag, as ``ros2 bag record -a`` would have it next to Universal_Robots_ROS2_Driver
and a camera driver:

- ``/joint_states`` at 500 Hz (the driver's joint_state_broadcaster): the six UR joint names,
  position, velocity, effort, with encoder noise, in the order the broadcaster happens to use
  (not the URDF's: ros2_control promises none, and a UR's ``shoulder_pan_joint`` often comes
  last), so readers must go by name;
- ``/tf`` at 500 Hz: what robot_state_publisher publishes from those joints for the URDF
  (``base -> shoulder_link -> ... -> wrist_3_link``) and the driver's tcp_pose_broadcaster
  (``base -> tool0_controller``);
- ``/tf_static``: the URDF's fixed joints (``base_link -> base``, ``wrist_3_link -> tool0``) and
  the camera's own frames (``tool0 -> camera_link -> camera_color_optical_frame``, the
  optical frame turned from the body frame as REP 103 has it);
- ``/camera/color/image_raw`` (``rgb8``) and ``/camera/color/camera_info`` at 30 Hz, stamped at
  exposure, on their own phase, logged a little later than stamped.

The arm moves smoothly between rest poses and waits at each; images shot while it moves are
rendered coarsely (they must not be chosen), still ones at full quality, by the mock scene.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from mcap_ros2.writer import Writer

from armstereo.camera_model import Intrinsics
from armstereo.kinematics import JOINT_NAMES, ArmModel
from armstereo.ros2 import types as R
from armstereo.transforms import invert, make_T, quaternion_xyzw, rot_x, rot_y, rot_z

CAMERA_FRAME = "camera_color_optical_frame"
IMAGE_TOPIC = "/camera/color/image_raw"
INFO_TOPIC = "/camera/color/camera_info"
# camera_link (x forward, z up) -> optical frame (z forward, x right, y down)
T_LINK_OPTICAL = make_T(rot_z(-math.pi / 2) @ rot_x(-math.pi / 2), [0, 0, 0])
TF_HZ, CAMERA_HZ = 500.0, 30.0
T0_NS = 1_712_000_000_000_000_000
BROADCAST_ORDER = (1, 2, 3, 4, 5, 0)  # indices into JOINT_NAMES


@dataclass
class DriverBag:
    """A built bag: its path, the rest joint vectors, the true camera pose at each rest
    (base, m), the intrinsics and the true mount."""

    path: Path
    rest_joints: list[np.ndarray]
    rest_cameras: list[np.ndarray]
    intrinsics: Intrinsics
    T_flange_camera: np.ndarray
    messages: dict[str, int] = field(default_factory=dict)


def urdf_joints(model: ArmModel) -> list[dict]:
    """The URDF's joints: name, type, parent, child, origin (4x4), axis."""
    out = []
    for j in ET.parse(model.urdf_path).getroot().iter("joint"):
        o = j.find("origin")
        xyz = [float(v) for v in o.get("xyz", "0 0 0").split()]
        r, p, y = (float(v) for v in o.get("rpy", "0 0 0").split())
        axis = j.find("axis")
        out.append({"name": j.get("name"), "type": j.get("type"),
                    "parent": j.find("parent").get("link"), "child": j.find("child").get("link"),
                    "origin": make_T(rot_z(y) @ rot_y(p) @ rot_x(r), xyz),
                    "axis": np.array([float(v) for v in axis.get("xyz").split()])
                    if axis is not None else None})
    return out


def _tf(parent: str, child: str, T: np.ndarray, t_ns: int) -> dict:
    x, y, z, w = quaternion_xyzw(T[:3, :3])
    return {"header": _header(t_ns, parent), "child_frame_id": child,
            "transform": {"translation": {"x": T[0, 3], "y": T[1, 3], "z": T[2, 3]},
                          "rotation": {"x": x, "y": y, "z": z, "w": w}}}


def _header(t_ns: int, frame: str) -> dict:
    sec, nsec = divmod(int(t_ns), 1_000_000_000)
    return {"stamp": {"sec": sec, "nanosec": nsec}, "frame_id": frame}


def _profile(rests: list[np.ndarray], rest_s: float, move_s: float):
    """q(t) (s from the start): rest, smooth cosine move, rest, ...; and the total time."""
    total = len(rests) * rest_s + (len(rests) - 1) * move_s

    def q_at(t: float) -> tuple[np.ndarray, int | None]:
        """Joints at t and the rest they are at (None while moving)."""
        seg = rest_s + move_s
        k = min(int(t // seg), len(rests) - 1)
        local = t - k * seg
        if local <= rest_s or k == len(rests) - 1:
            return rests[k], k
        s = (1 - math.cos(math.pi * min(1.0, (local - rest_s) / move_s))) / 2
        return rests[k] + s * (rests[k + 1] - rests[k]), None

    return q_at, total


def build_driver_bag(path: Path, model: ArmModel, rests: list[np.ndarray], intr: Intrinsics,
                     render, *, rest_s: float = 0.45, move_s: float = 0.45,
                     noise_rad: float = 2e-6, tf_hz: float = TF_HZ,
                     camera_hz: float = CAMERA_HZ, seed: int = 0) -> DriverBag:
    """Write the bag (a .mcap file) of the arm visiting ``rests`` (joint vectors) with
    ``model.mount`` as the camera's TF; ``render(T_base_camera, intr, rest) -> image`` (BGR or
    grey) draws what the camera sees (``rest``: the rest's number, None while moving)."""
    rng = np.random.default_rng(seed)
    store = R.typestore("jazzy")
    joints = urdf_joints(model)
    assert all(j["axis"] is None or list(j["axis"]) == [0, 0, 1] for j in joints), \
        "the bundled URDFs turn about z"
    T_fc = model.mount.T_flange_camera
    T_tool0_link = T_fc @ invert(T_LINK_OPTICAL)
    q_at, total = _profile(rests, rest_s, move_s)
    counts: dict[str, int] = {}
    with open(path, "wb") as f:
        w = Writer(f)
        schemas = {t: w.register_msgdef(t, store.generate_msgdef(t, ros_version=2)[0])
                   for t in (R.TF_MESSAGE, R.JOINT_STATE, R.IMAGE, R.CAMERA_INFO)}

        def put(topic: str, msgtype: str, msg: dict, t_ns: int) -> None:
            w.write_message(topic, schemas[msgtype], msg, log_time=t_ns, publish_time=t_ns)
            counts[topic] = counts.get(topic, 0) + 1

        static = [_tf(j["parent"], j["child"], j["origin"], T0_NS) for j in joints
                  if j["type"] == "fixed"]
        static += [_tf("tool0", "camera_link", T_tool0_link, T0_NS),
                   _tf("camera_link", CAMERA_FRAME, T_LINK_OPTICAL, T0_NS)]
        put(R.TOPIC_TF_STATIC, R.TF_MESSAGE, {"transforms": static}, T0_NS)
        names = [JOINT_NAMES[i] for i in BROADCAST_ORDER]
        for k in range(int(total * tf_hz) + 1):
            t_ns = T0_NS + int(round(k * 1e9 / tf_hz))
            q, _ = q_at(k / tf_hz)
            q = q + rng.normal(0.0, noise_rad, 6)
            put("/joint_states", R.JOINT_STATE,
                {"header": _header(t_ns, ""), "name": names,
                 "position": [q[i] for i in BROADCAST_ORDER], "velocity": [0.0] * 6,
                 "effort": [0.0] * 6}, t_ns + 100_000)
            tfs = [_tf(j["parent"], j["child"], j["origin"] @ make_T(
                rot_z(q[JOINT_NAMES.index(j["name"])]), [0, 0, 0]), t_ns)
                for j in joints if j["type"] == "revolute"]
            tfs.append(_tf("base", "tool0_controller", model.flange_pose(q), t_ns))
            put(R.TOPIC_TF, R.TF_MESSAGE, {"transforms": tfs}, t_ns + 200_000)
        info = _camera_info(intr)
        cache: dict[int, np.ndarray] = {}
        for k in range(int(total * camera_hz)):
            t_s = 0.0073 + k / camera_hz
            t_ns = T0_NS + int(round(t_s * 1e9))
            q, rest = q_at(t_s)
            if rest is not None and rest not in cache:
                cache[rest] = render(model.flange_pose(q) @ T_fc, intr, rest)
            img = cache[rest] if rest is not None else render(model.flange_pose(q) @ T_fc,
                                                             intr, None)
            put(IMAGE_TOPIC, R.IMAGE, {"header": _header(t_ns, CAMERA_FRAME),
                                       **_image_fields(img)}, t_ns + 15_000_000)
            put(INFO_TOPIC, R.CAMERA_INFO, {**info, "header": _header(t_ns, CAMERA_FRAME)},
                t_ns + 15_000_000)
        w.finish()
    return DriverBag(path, list(rests), [model.flange_pose(q) @ T_fc for q in rests], intr,
                     T_fc, counts)


def _image_fields(img: np.ndarray) -> dict:
    """A camera driver's Image fields: colour as ``rgb8``, grey as ``mono8``."""
    h, w = img.shape[:2]
    if img.ndim == 2:
        return {"height": h, "width": w, "encoding": "mono8", "is_bigendian": 0, "step": w,
                "data": img.tobytes()}
    rgb = np.ascontiguousarray(img[:, :, ::-1])
    return {"height": h, "width": w, "encoding": "rgb8", "is_bigendian": 0, "step": 3 * w,
            "data": rgb.tobytes()}


def _camera_info(intr: Intrinsics) -> dict:
    K = np.asarray(intr.K, dtype=float)
    return {"height": intr.height, "width": intr.width, "distortion_model": "plumb_bob",
            "d": [float(v) for v in np.resize(intr.dist, 5)],
            "k": K.reshape(-1).tolist(), "r": np.eye(3).reshape(-1).tolist(),
            "p": np.hstack([K, np.zeros((3, 1))]).reshape(-1).tolist(),
            "binning_x": 0, "binning_y": 0,
            "roi": {"x_offset": 0, "y_offset": 0, "height": 0, "width": 0,
                    "do_rectify": False}}


def as_sqlite3_bag(src: Path, out: Path, distro: str = "jazzy") -> Path:
    """The bag folder ``out`` (metadata.yaml + .db3) holding ``src``'s messages byte for
    byte: what ``ros2 bag record -s sqlite3`` would have written."""
    from mcap.reader import make_reader
    from rosbags.rosbag2 import StoragePlugin
    from rosbags.rosbag2 import Writer as BagWriter

    store = R.typestore(distro)
    with open(src, "rb") as f, BagWriter(out, version=R.distro(distro).metadata_version,
                                         storage_plugin=StoragePlugin.SQLITE3) as w:
        w.set_custom_data("recorder", "tests")
        conns = {}
        for schema, channel, message in make_reader(f).iter_messages(log_time_order=True):
            if channel.topic not in conns:
                conns[channel.topic] = w.add_connection(
                    channel.topic, schema.name, typestore=store,
                    offered_qos_profiles=R.qos("static" if "static" in channel.topic
                                               else "default"))
            w.write(conns[channel.topic], message.log_time, message.data)
    return out
