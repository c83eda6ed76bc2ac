"""A tiny bag (a few hundred messages, 16x12 images) to break in every way: the camera rests at
x = 0, moves 5 cm along its x axis and rests again. Built as a list of records the tests edit
before writing, with mcap-ros2-support."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from mcap.writer import CompressionType
from mcap_ros2.writer import Writer

from armstereo.ros2 import types as R

T0 = 1_700_000_000_000_000_000
IMAGE = "/cam/image_raw"
INFO = "/cam/camera_info"
CAMERA = "cam_optical"
W, H = 16, 12


@dataclass
class Record:
    topic: str
    msgtype: str
    msg: dict
    log_ns: int


@dataclass
class Tiny:
    records: list[Record] = field(default_factory=list)
    msgdefs: dict[str, str] = field(default_factory=dict)  # type -> definition text

    def drop(self, topic: str) -> Tiny:
        self.records = [r for r in self.records if r.topic != topic]
        return self

    def on(self, topic: str) -> list[Record]:
        return [r for r in self.records if r.topic == topic]

    def write(self, path: Path, *, plain: bool = False) -> Path:
        """Write the bag; ``plain``: no chunk compression and no CRCs, so that damaged bytes
        reach the message decoder instead of failing a checksum."""
        store = R.typestore("humble")
        with open(path, "wb") as f:
            w = Writer(f, compression=CompressionType.NONE, enable_crcs=False) if plain \
                else Writer(f)
            schemas = {}
            for r in sorted(self.records, key=lambda r: r.log_ns):
                if r.msgtype not in schemas:
                    text = self.msgdefs.get(r.msgtype) or store.generate_msgdef(
                        r.msgtype, ros_version=2)[0]
                    schemas[r.msgtype] = w.register_msgdef(r.msgtype, text)
                w.write_message(r.topic, schemas[r.msgtype], r.msg, log_time=r.log_ns,
                                publish_time=r.log_ns)
            w.finish()
        return path


def header(t_ns: int, frame: str) -> dict:
    sec, nsec = divmod(t_ns, 1_000_000_000)
    return {"stamp": {"sec": sec, "nanosec": nsec}, "frame_id": frame}


def tf(parent: str, child: str, xyz, t_ns: int) -> dict:
    return {"header": header(t_ns, parent), "child_frame_id": child,
            "transform": {"translation": dict(zip("xyz", map(float, xyz), strict=True)),
                          "rotation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}}}


def x_at(t_s: float) -> float:
    """Camera x (m): rest until 0.5 s, a 0.2 s move of 5 cm, rest until 1.2 s."""
    return 0.05 * min(1.0, max(0.0, (t_s - 0.5) / 0.2))


def tiny(seed: int = 0) -> Tiny:
    rng = np.random.default_rng(seed)
    K = [20.0, 0.0, 7.5, 0.0, 20.0, 5.5, 0.0, 0.0, 1.0]
    b = Tiny()
    b.records.append(Record(R.TOPIC_TF_STATIC, R.TF_MESSAGE,
                            {"transforms": [tf("tool0", CAMERA, (0, 0, 0.02), T0)]}, T0))
    for k in range(121):  # 100 Hz
        t = T0 + k * 10_000_000
        b.records.append(Record(R.TOPIC_TF, R.TF_MESSAGE, {"transforms": [
            tf("base", "tool0", (x_at(k / 100), 0.0, 0.5), t)]}, t + 1000))
    for k in range(24):  # 20 Hz
        t = T0 + 3_000_000 + k * 50_000_000
        img = rng.integers(0, 256, (H, W), dtype=np.uint8)
        b.records.append(Record(IMAGE, R.IMAGE, {
            "header": header(t, CAMERA), "height": H, "width": W, "encoding": "mono8",
            "is_bigendian": 0, "step": W, "data": img.tobytes()}, t + 5_000_000))
        b.records.append(Record(INFO, R.CAMERA_INFO, {
            "header": header(t, CAMERA), "height": H, "width": W,
            "distortion_model": "plumb_bob", "d": [0.0] * 5, "k": K,
            "r": [1.0, 0, 0, 0, 1.0, 0, 0, 0, 1.0],
            "p": K[:3] + [0.0] + K[3:6] + [0.0] + K[6:] + [0.0], "binning_x": 0,
            "binning_y": 0, "roi": {"x_offset": 0, "y_offset": 0, "height": 0, "width": 0,
                                    "do_rectify": False}}, t + 5_000_000))
    return b
