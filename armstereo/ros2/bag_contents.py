"""What an import needs from a bag: image stamps, camera infos, TF, joint states, armstereo's
events (first pass, no pixels kept), and then the pixels of the chosen images (second pass).

Images are ``sensor_msgs/msg/Image`` (8-bit: ``bgr8``, ``rgb8``, ``mono8``, ``bgra8``,
``rgba8``, ``yuv422``/``uyvy``, ``yuv422_yuy2``/``yuyv``) or ``CompressedImage`` (PNG or JPEG,
as compressed_image_transport publishes them), decoded to armstereo's uint8 BGR or grey.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field

import cv2
import numpy as np

from armstereo.camera_model import Intrinsics
from armstereo.errors import ArmstereoError, RecordingError
from armstereo.recording.decode import decode_image
from armstereo.ros2 import types as R
from armstereo.ros2.bag_reader import BagReader
from armstereo.ros2.poses import JointSeries
from armstereo.ros2.tf_buffer import TfBuffer

_CHANNELS = {"bgr8": 3, "8UC3": 3, "rgb8": 3, "mono8": 1, "8UC1": 1, "bgra8": 4, "8UC4": 4,
             "rgba8": 4, "yuv422": 2, "uyvy": 2, "yuv422_yuy2": 2, "yuyv": 2}
_TO_BGR = {"rgb8": cv2.COLOR_RGB2BGR, "bgra8": cv2.COLOR_BGRA2BGR, "8UC4": cv2.COLOR_BGRA2BGR,
           "rgba8": cv2.COLOR_RGBA2BGR, "yuv422": cv2.COLOR_YUV2BGR_UYVY,
           "uyvy": cv2.COLOR_YUV2BGR_UYVY, "yuv422_yuy2": cv2.COLOR_YUV2BGR_YUY2,
           "yuyv": cv2.COLOR_YUV2BGR_YUY2}
ROS_DISTORTION = {"plumb_bob": (4, 5), "rational_polynomial": (8, 8)}


@dataclass(frozen=True)
class Topics:
    """The bag's topics an import reads (None: not read)."""

    image: str
    camera_info: str
    tf: str | None = R.TOPIC_TF
    tf_static: str | None = R.TOPIC_TF_STATIC
    joint_states: str | None = None
    events: str | None = None
    depth: str | None = None


@dataclass(frozen=True)
class ImageRef:
    """An image message: its number on the topic, log time and header stamp (ns), frame."""

    number: int
    log_ns: int
    stamp_ns: int
    frame_id: str


@dataclass
class Contents:
    images: list[ImageRef] = field(default_factory=list)
    camera_infos: list[tuple[int, Intrinsics, str]] = field(default_factory=list)
    tf: TfBuffer = field(default_factory=TfBuffer)
    joints: JointSeries | None = None
    events: list[dict] = field(default_factory=list)
    depth_stamps: dict[int, int] = field(default_factory=dict)  # stamp -> message number

    def intrinsics_at(self, stamp_ns: int) -> Intrinsics | None:
        """The camera info stamped ``stamp_ns``, else the latest one before it, else the
        first one (a driver that published its camera info once, late)."""
        best = None
        for t, intr, _ in self.camera_infos:
            if t == stamp_ns:
                return intr
            if t <= stamp_ns and (best is None or t >= best[0]):
                best = (t, intr)
        if best is not None:
            return best[1]
        return self.camera_infos[0][1] if self.camera_infos else None


def collect(bag: BagReader, topics: Topics, joint_names: tuple[str, ...]) -> Contents:
    """First pass over ``topics`` of ``bag`` (no pixels kept)."""
    c = Contents(joints=JointSeries(joint_names) if topics.joint_states else None)
    wanted = [t for t in (topics.image, topics.camera_info, topics.tf, topics.tf_static,
                          topics.joint_states, topics.events, topics.depth) if t]
    numbers = {t: 0 for t in wanted}
    for topic, t_ns, msg in bag.messages(wanted):
        n = numbers[topic]
        numbers[topic] += 1
        try:
            _collect_one(c, topics, topic, t_ns, n, msg)
        except (ValueError, TypeError, KeyError, ArmstereoError, AttributeError):
            bag.bad_message(topic)
    c.tf.finish()
    if c.joints is not None:
        c.joints.finish(topics.joint_states)
    _check_order(c.images, topics.image)
    return c


def _collect_one(c: Contents, topics: Topics, topic: str, t_ns: int, n: int, msg) -> None:
    if topic == topics.image:
        c.images.append(ImageRef(n, t_ns, R.stamp_ns(msg.header.stamp),
                                 msg.header.frame_id.lstrip("/")))
    elif topic == topics.camera_info:
        c.camera_infos.append((R.stamp_ns(msg.header.stamp), intrinsics(msg),
                               msg.header.frame_id.lstrip("/")))
    elif topic in (topics.tf, topics.tf_static):
        c.tf.add(msg, static=topic == topics.tf_static, stamp_of=lambda h: R.stamp_ns(h.stamp))
    elif topic == topics.joint_states:
        if not c.joints.add(msg.name, msg.position, R.stamp_ns(msg.header.stamp)):
            return
    elif topic == topics.events:
        obj = json.loads(msg.data)
        if not isinstance(obj, dict) or obj.get("event") not in ("view", "pair"):
            raise ValueError("not an armstereo capture event")
        c.events.append(obj)
    elif topic == topics.depth:
        c.depth_stamps.setdefault(R.stamp_ns(msg.header.stamp), n)


def _check_order(images: list[ImageRef], topic: str) -> None:
    stamps = np.array([im.stamp_ns for im in images], dtype=np.int64)
    back = np.flatnonzero(np.diff(stamps) <= 0)
    if back.size:
        k = int(back[0])
        raise RecordingError(f"{topic}: image {k + 1} is stamped {stamps[k + 1]} ns, not after "
                             f"image {k} ({stamps[k]} ns); the bag's time stamps are out of "
                             "order")


def intrinsics(msg) -> Intrinsics:
    """Intrinsics of a CameraInfo (ValueError for what armstereo cannot model)."""
    d = np.asarray(msg.d, dtype=float).reshape(-1)
    model = msg.distortion_model.strip()
    if model in ROS_DISTORTION:
        lo, hi = ROS_DISTORTION[model]
        if not lo <= d.size <= hi:
            raise ValueError(f"{model} with {d.size} coefficients")
    elif model or np.any(d):
        raise ValueError(f"distortion model {model!r} is not plumb_bob or rational_polynomial")
    if msg.binning_x > 1 or msg.binning_y > 1 or msg.roi.width or msg.roi.height:
        raise ValueError("binning or a region of interest (K is for the full sensor)")
    return Intrinsics(int(msg.width), int(msg.height), np.asarray(msg.k, float).reshape(3, 3),
                      d if d.size else np.zeros(5))


def load_images(bag: BagReader, topic: str, numbers: dict[int, Intrinsics | None]
                ) -> dict[int, np.ndarray]:
    """Second pass: the decoded images numbered ``numbers`` (-> their intrinsics, for the size
    check). RecordingError naming the image when one cannot be used."""
    out: dict[int, np.ndarray] = {}
    n = -1
    for _, _, msg in bag.messages([topic]):
        n += 1
        if n in numbers:
            out[n] = decode(msg, numbers[n], f"{topic} image {n}")
            if len(out) == len(numbers):
                break
    return out


def decode(msg, intr: Intrinsics | None, what: str) -> np.ndarray:
    """uint8 BGR or grey pixels of an Image or CompressedImage message."""
    if hasattr(msg, "format"):  # CompressedImage
        fmt = msg.format.lower()
        if "compresseddepth" in fmt:
            raise RecordingError(f"{what}: compressedDepth images are depth, not camera images")
        kind = "jpeg" if ("jpeg" in fmt or "jpg" in fmt) else "png" if "png" in fmt else fmt
        return decode_image(bytes(msg.data), kind, intr, what)
    enc = msg.encoding
    if enc not in _CHANNELS:
        raise RecordingError(f"{what}: encoding {enc!r} is not supported (8-bit colour or grey:"
                             f" {', '.join(sorted(_CHANNELS))})")
    h, w, step, ch = int(msg.height), int(msg.width), int(msg.step), _CHANNELS[enc]
    data = np.asarray(msg.data, dtype=np.uint8)
    if h < 1 or w < 1 or step < w * ch or data.size < step * h:
        raise RecordingError(f"{what}: {w}x{h} {enc} with step {step} does not fit "
                             f"{data.size} data bytes")
    rows = data[:step * h].reshape(h, step)[:, :w * ch]
    img = rows.reshape(h, w, ch) if ch > 1 else rows.reshape(h, w)
    if enc in _TO_BGR:
        img = cv2.cvtColor(img, _TO_BGR[enc])
    if intr is not None and (w, h) != intr.size:
        raise RecordingError(f"{what} is {w}x{h} but its camera info says "
                             f"{intr.width}x{intr.height}")
    return np.ascontiguousarray(img)


def load_depth(bag: BagReader, topic: str, numbers: dict[int, int]) -> dict[int, np.ndarray]:
    """Second pass over a ``32FC1`` depth topic: message number -> float32 metres."""
    out: dict[int, np.ndarray] = {}
    n = -1
    for _, _, msg in bag.messages([topic]):
        n += 1
        if n not in numbers:
            continue
        h, w = int(msg.height), int(msg.width)
        data = np.asarray(msg.data, dtype=np.uint8)
        if msg.encoding != "32FC1" or msg.step != 4 * w or data.size != 4 * w * h:
            bag.bad_message(topic)
            continue
        out[n] = data.view("<f4").reshape(h, w).astype(np.float32)
    return out
