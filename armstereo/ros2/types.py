"""ROS 2 message types, distributions and QoS profiles: what every bag we write or read shares.

The message definitions are the ones the ROS 2 distributions ship, as collected in the type
stores of ``rosbags`` (``Stores.ROS2_HUMBLE``, ``Stores.ROS2_JAZZY``). For every type armstereo
uses, Humble and Jazzy agree field by field (their RIHS01 type hashes are equal); only
``visualization_msgs/msg/Marker`` differs, by one constant (Jazzy's ``ARROW_STRIP = 12``), so
the two bags differ in their schema text and metadata version, not in their bytes.

``rosbags`` is imported only here (and in the modules that read and write bags), through
:func:`armstereo.backends.require_extra`: without the extra, the first use is a one-line
error that says ``pip install 'armstereo[ros2]'``.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache

from armstereo.backends import require_extra
from armstereo.errors import ConfigError

IMAGE = "sensor_msgs/msg/Image"
COMPRESSED_IMAGE = "sensor_msgs/msg/CompressedImage"
CAMERA_INFO = "sensor_msgs/msg/CameraInfo"
POINT_CLOUD2 = "sensor_msgs/msg/PointCloud2"
JOINT_STATE = "sensor_msgs/msg/JointState"
TF_MESSAGE = "tf2_msgs/msg/TFMessage"
MARKER = "visualization_msgs/msg/Marker"
MARKER_ARRAY = "visualization_msgs/msg/MarkerArray"
STRING = "std_msgs/msg/String"
IMAGE_TYPES = (IMAGE, COMPRESSED_IMAGE)

TOPIC_TF = "/tf"
TOPIC_TF_STATIC = "/tf_static"


@dataclass(frozen=True)
class Distro:
    """A ROS 2 distribution: its rosbags type store and the rosbag2 metadata version its
    ``ros2 bag`` reads (Humble reads version 8, whose QoS profiles are one YAML string, and
    not Jazzy's version 9, whose profiles are a YAML list)."""

    name: str
    store: str
    metadata_version: int


DISTROS = {"humble": Distro("humble", "ROS2_HUMBLE", 8),
           "jazzy": Distro("jazzy", "ROS2_JAZZY", 9)}
# A Humble bag plays on Humble and on Jazzy (rosbag2 reads older metadata versions).
DEFAULT_DISTRO = "humble"


def distro(name: str) -> Distro:
    """The distribution called ``name``; ConfigError naming the known ones otherwise."""
    if name not in DISTROS:
        raise ConfigError(f"unknown ROS 2 distribution {name!r}; choose one of "
                          f"{', '.join(DISTROS)}")
    return DISTROS[name]


@cache
def typestore(name: str = DEFAULT_DISTRO):
    """The rosbags type store of distribution ``name`` (cached; needs the ros2 extra)."""
    require_extra("ros2")
    from rosbags.typesys import Stores, get_typestore

    return get_typestore(getattr(Stores, distro(name).store))


def msg_class(store, msgtype: str) -> type:
    """The message class of ``msgtype`` in ``store`` (a rosbags dataclass)."""
    return store.types[msgtype]


def time_msg(store, t_ns: int):
    """``builtin_interfaces/msg/Time`` of integer nanoseconds since the epoch."""
    sec, nanosec = divmod(int(t_ns), 1_000_000_000)
    return msg_class(store, "builtin_interfaces/msg/Time")(sec=sec, nanosec=nanosec)


def stamp_ns(stamp) -> int:
    """Integer nanoseconds of a ``builtin_interfaces/msg/Time`` (sec may be negative)."""
    return int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec)


def header(store, t_ns: int, frame_id: str):
    """``std_msgs/msg/Header`` at ``t_ns`` in ``frame_id``."""
    return msg_class(store, "std_msgs/msg/Header")(stamp=time_msg(store, t_ns),
                                                   frame_id=str(frame_id))


def qos(kind: str = "default") -> list:
    """Offered QoS profiles for a topic, as ``ros2 bag play`` re-offers them.

    ``static``: ``/tf_static`` as tf2's static broadcaster offers it (reliable, transient
    local, keep last 1), so a late subscriber (rviz) still gets the mount; ``tf``: keep last
    100 as tf2's broadcaster; ``default``: reliable, volatile, keep last 10. Durations 0 mean
    the middleware's default (none).
    """
    from rosbags.interfaces import (
        Qos,
        QosDurability,
        QosHistory,
        QosLiveliness,
        QosReliability,
        QosTime,
    )

    depth = {"static": 1, "tf": 100, "default": 10}[kind]
    durability = QosDurability.TRANSIENT_LOCAL if kind == "static" else QosDurability.VOLATILE
    zero = QosTime(0, 0)
    return [Qos(QosHistory.KEEP_LAST, depth, QosReliability.RELIABLE, durability, zero, zero,
                QosLiveliness.AUTOMATIC, zero, False)]
