"""RealSense recordings made without hardware, through the SDK itself: a ``software_device``
(the SDK's own simulated device: name, serial, a colour sensor with its intrinsics and options)
recorded by ``rs.recorder`` into the file format the SDK plays back (``.db3`` from SDK 2.56
on, ``.bag`` before). Each frame carries the metadata a D400 colour sensor sends (actual
exposure, gain, white balance, the device's frame time stamp)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from armstereo.camera_model import Intrinsics
from drivers.realsense.sdk import rs as load_rs

SERIAL = "923322071108"
NAME = "Intel RealSense D435 (software device)"
FRAME_PERIOD_MS = 1000 / 30
START_MS = 5000.0  # the device clock's time of the first frame


def option_range(rs, lo: float, hi: float, step: float, default: float):
    # pyrealsense2's 4-argument constructor swaps step and default; set the fields by name
    r = rs.option_range()
    r.min, r.max, r.step, r.default = lo, hi, step, default
    return r


def software_camera(intr: Intrinsics, *, fps: int = 30, serial: str = SERIAL,
                    model: str = "brown_conrady", locked: bool = False):
    """(device, colour sensor, profile) of a software device with a BGR8 colour stream of
    ``intr``'s size and calibration, and exposure, gain, white balance and their auto modes
    as writable options, as on a live camera (auto modes on unless ``locked``)."""
    rs = load_rs()
    dev = rs.software_device()
    dev.register_info(rs.camera_info.name, NAME)
    dev.register_info(rs.camera_info.serial_number, serial)
    dev.register_info(rs.camera_info.firmware_version, "5.16.0.1")
    sensor = dev.add_sensor("RGB Camera")
    ri = rs.intrinsics()
    ri.width, ri.height = intr.width, intr.height
    ri.fx, ri.fy, ri.ppx, ri.ppy = intr.K[0, 0], intr.K[1, 1], intr.K[0, 2], intr.K[1, 2]
    ri.model = getattr(rs.distortion, model)
    ri.coeffs = [float(c) for c in list(intr.dist[:5]) + [0.0] * (5 - len(intr.dist[:5]))]
    vs = rs.video_stream()
    vs.type, vs.index, vs.uid = rs.stream.color, 0, 1
    vs.width, vs.height, vs.fps, vs.bpp, vs.fmt = intr.width, intr.height, fps, 3, \
        rs.format.bgr8
    vs.intrinsics = ri
    profile = sensor.add_video_stream(vs)
    for opt, rng in ((rs.option.exposure, (1.0, 10000.0, 1.0, 156.0)),
                     (rs.option.gain, (0.0, 128.0, 1.0, 64.0)),
                     (rs.option.white_balance, (2800.0, 6500.0, 10.0, 4600.0)),
                     (rs.option.enable_auto_exposure, (0.0, 1.0, 1.0, 1.0)),
                     (rs.option.enable_auto_white_balance, (0.0, 1.0, 1.0, 1.0))):
        sensor.add_option(opt, option_range(rs, *rng), True)
    for auto in (rs.option.enable_auto_exposure, rs.option.enable_auto_white_balance):
        sensor.set_option(auto, 0.0 if locked else 1.0)
    return dev, sensor, profile


def push(rs, sensor, profile, image: np.ndarray, k: int, settings: dict | None = None,
         t0_ms: float = START_MS, host_ms: float | None = None) -> None:
    """Hand frame ``k`` (BGR uint8) to the software sensor, with its metadata; time stamped
    on the device's own clock, or with ``host_ms`` in the host-synchronised (global) domain."""
    h, w = image.shape[:2]
    f = rs.software_video_frame()
    f.pixels = np.ascontiguousarray(image)
    f.stride, f.bpp = w * 3, 3
    f.timestamp = t0_ms + k * FRAME_PERIOD_MS if host_ms is None else host_ms
    f.domain = rs.timestamp_domain.hardware_clock if host_ms is None \
        else rs.timestamp_domain.global_time
    f.frame_number = k
    f.profile = profile.as_video_stream_profile()
    md = rs.frame_metadata_value
    s = {"exposure": 156.0, "gain": 64.0, "white_balance_k": 4600.0, **(settings or {})}
    sensor.set_metadata(md.actual_exposure, int(s["exposure"]))
    sensor.set_metadata(md.gain_level, int(s["gain"]))
    sensor.set_metadata(md.white_balance, int(s["white_balance_k"]))
    sensor.set_metadata(md.frame_timestamp, int(round(f.timestamp * 1000)))
    sensor.on_video_frame(f)


def make_recording(path: Path, images: list[np.ndarray], intr: Intrinsics, *,
                   settings: list[dict] | None = None, serial: str = SERIAL,
                   model: str = "brown_conrady", locked: bool = True) -> Path:
    """Record ``images`` (BGR uint8, ``intr``'s size) as a RealSense recording at ``path``
    with the suffix the SDK writes (``.db3``, or ``.bag`` for older SDKs); per-frame
    ``settings`` as :func:`push` takes them; ``locked``: auto exposure and auto white balance
    were off. Returns the file written."""
    rs = load_rs()
    dev, sensor, profile = software_camera(intr, serial=serial, model=model, locked=locked)
    try:
        path = Path(path).with_suffix(".db3")
        recorder = rs.recorder(str(path), dev)
    except RuntimeError:  # SDKs before rosbag2 record ROS 1 bags
        path = Path(path).with_suffix(".bag")
        recorder = rs.recorder(str(path), dev)
    queue = rs.frame_queue(len(images) + 1, keep_frames=True)
    sensor.open(profile)
    sensor.start(queue)
    for k, image in enumerate(images):
        push(rs, sensor, profile, image, k, (settings or [{}] * len(images))[k])
        queue.wait_for_frame(2000)
    sensor.stop()
    sensor.close()
    del recorder  # the recording is finished when the recorder goes
    return path
