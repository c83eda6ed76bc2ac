"""OpenCVCamera against a fake cv2.VideoCapture: open and size errors, flushing, timeouts and
the exposure / white-balance lock."""

from __future__ import annotations

import logging
import threading

import cv2
import numpy as np
import pytest

from armstereo.camera_model import Intrinsics
from armstereo.clock import SimClock
from armstereo.errors import (
    CameraTimeout,
    ConfigError,
    ConnectionFailed,
    NotConnected,
)
from drivers.opencv import camera as camera_module
from drivers.opencv.camera import OpenCVCamera

INTRINSICS = Intrinsics(640, 480, np.array([[600.0, 0, 319.5], [0, 600.0, 239.5], [0, 0, 1]]))


class FakeDevice:
    """What the fake captures deliver; tests change it to make the device misbehave."""

    def __init__(self):
        self.opens = True
        self.frames = True                 # grab() succeeds
        self.size: tuple[int, int] | None = None  # forced (w, h); None = whatever was set
        self.gate: threading.Event | None = None  # grab() blocks until set
        self.ignored: set[int] = set()      # props whose set() the driver refuses
        self.backend = "V4L2"
        self.captures: list[FakeCapture] = []


class FakeCapture:
    def __init__(self, device: FakeDevice, index, api):
        self.dev, self.index, self.api = device, index, api
        self.props = {cv2.CAP_PROP_FRAME_WIDTH: 1920.0, cv2.CAP_PROP_FRAME_HEIGHT: 1080.0,
                      cv2.CAP_PROP_AUTO_EXPOSURE: 3.0, cv2.CAP_PROP_EXPOSURE: 166.0,
                      cv2.CAP_PROP_GAIN: 4.0, cv2.CAP_PROP_AUTO_WB: 1.0,
                      cv2.CAP_PROP_WB_TEMPERATURE: 4600.0}
        self.sets: list[tuple[int, float]] = []
        self.grabs = 0
        self.releases = 0
        device.captures.append(self)

    def isOpened(self):
        return self.dev.opens

    def set(self, prop, value):
        self.sets.append((prop, value))
        if prop in self.dev.ignored:
            return False
        self.props[prop] = float(value)
        return True

    def get(self, prop):
        return self.props.get(prop, 0.0)

    def grab(self):
        self.grabs += 1
        if self.dev.gate is not None:
            self.dev.gate.wait(2.0)
        return self.dev.frames

    def retrieve(self):
        w, h = self.dev.size or (int(self.props[cv2.CAP_PROP_FRAME_WIDTH]),
                                 int(self.props[cv2.CAP_PROP_FRAME_HEIGHT]))
        return True, np.full((h, w, 3), self.grabs % 256, dtype=np.uint8)

    def release(self):
        self.releases += 1

    def getBackendName(self):
        return self.dev.backend


@pytest.fixture
def dev(monkeypatch) -> FakeDevice:
    device = FakeDevice()
    monkeypatch.setattr(cv2, "VideoCapture",
                        lambda index, api=cv2.CAP_ANY: FakeCapture(device, index, api))
    monkeypatch.setattr(camera_module, "READ_GRACE_S", 0.01)
    yield device
    if device.gate is not None:
        device.gate.set()


def test_open_failure_names_the_device(dev):
    dev.opens = False
    cam = OpenCVCamera("/dev/video7", INTRINSICS, timeout=0.2)
    with pytest.raises(ConnectionFailed, match="cannot open camera '/dev/video7'"):
        cam.connect()
    assert dev.captures[0].releases == 1


def test_size_is_requested_and_a_wrong_size_refused(dev):
    dev.size = (1280, 720)
    cam = OpenCVCamera(0, INTRINSICS, timeout=0.2)
    with pytest.raises(ConfigError, match="camera 0 delivers 1280x720 .* for 640x480"):
        cam.connect()
    cap = dev.captures[0]
    assert (cv2.CAP_PROP_FRAME_WIDTH, 640) in cap.sets
    assert (cv2.CAP_PROP_FRAME_HEIGHT, 480) in cap.sets
    assert cap.releases == 1


def test_grab_flushes_the_requested_number_of_frames(dev):
    clock = SimClock()
    with OpenCVCamera(0, INTRINSICS, timeout=0.2, flush_frames=3, clock=clock) as cam:
        cap = dev.captures[0]
        before = cap.grabs
        frame = cam.grab()
        assert cap.grabs - before == 4  # 3 discarded + the kept one
        assert frame.image.shape == (480, 640, 3) and frame.image.dtype == np.uint8
        assert frame.image[0, 0, 0] == cap.grabs % 256  # pixels of the last grab
        assert frame.timestamp_ns == clock.now_ns()
        cam.flush_frames = 0
        before = cap.grabs
        cam.grab()
        assert cap.grabs - before == 1


def test_no_frame_times_out_naming_the_device(dev):
    with OpenCVCamera(2, INTRINSICS, timeout=0.2) as cam:
        dev.frames = False
        with pytest.raises(CameraTimeout, match=r"camera 2 delivered no frame within 0\.05 s"):
            cam.grab(timeout=0.05)


def test_blocked_device_times_out_and_close_does_not_hang(dev):
    cam = OpenCVCamera(0, INTRINSICS, timeout=0.1, flush_frames=0)
    cam.connect()
    dev.gate = threading.Event()
    with pytest.raises(CameraTimeout, match="camera 0"):
        cam.grab(timeout=0.05)
    cam.close()  # the read is still blocked: release is queued behind it
    dev.gate.set()


def test_no_first_frame_fails_connect(dev):
    dev.frames = False
    with pytest.raises(ConnectionFailed, match="opened but delivered no frame within 0.1 s"):
        OpenCVCamera(0, INTRINSICS, timeout=0.1).connect()
    assert dev.captures[0].releases == 1


def test_auto_exposure_and_white_balance_are_turned_off_and_values_pinned(dev):
    with OpenCVCamera(0, INTRINSICS, timeout=0.2, exposure=50.0, gain=2.0) as cam:
        sets = dev.captures[0].sets
        assert (cv2.CAP_PROP_AUTO_EXPOSURE, 1.0) in sets  # V4L2 "manual"
        assert (cv2.CAP_PROP_AUTO_WB, 0.0) in sets
        assert sets.index((cv2.CAP_PROP_AUTO_EXPOSURE, 1.0)) < \
            sets.index((cv2.CAP_PROP_EXPOSURE, 50.0))
        assert (cv2.CAP_PROP_GAIN, 2.0) in sets
        assert (cv2.CAP_PROP_WB_TEMPERATURE, 4600.0) in sets  # current value, locked
        assert cam.settings == {"auto_exposure": 1.0, "exposure": 50.0, "gain": 2.0,
                                "auto_white_balance": 0.0, "white_balance": 4600.0}


def test_non_v4l2_backend_uses_legacy_manual_value_and_ignored_props_warn(dev, caplog):
    dev.backend = "DSHOW"
    dev.ignored = {cv2.CAP_PROP_AUTO_WB}
    with caplog.at_level(logging.WARNING, logger="drivers.opencv.camera"):
        with OpenCVCamera(0, INTRINSICS, timeout=0.2):
            pass
    assert (cv2.CAP_PROP_AUTO_EXPOSURE, 0.25) in dev.captures[0].sets
    assert "ignored auto_white_balance = 0 (reads back 1)" in caplog.text


def test_close_is_idempotent_and_grab_needs_connect(dev):
    cam = OpenCVCamera(0, INTRINSICS, timeout=0.2)
    with pytest.raises(NotConnected, match="not connected"):
        cam.grab()
    cam.connect()
    cam.close()
    cam.close()
    assert dev.captures[0].releases == 1
    with pytest.raises(NotConnected, match="not connected"):
        cam.grab()


def test_device_names_and_backends(dev):
    pipeline = "v4l2src ! videoconvert ! appsink"
    assert OpenCVCamera(pipeline, INTRINSICS).api == cv2.CAP_GSTREAMER
    assert OpenCVCamera("1", INTRINSICS).device == 1
    assert OpenCVCamera(0, INTRINSICS, backend="v4l2").api == cv2.CAP_V4L2
    with pytest.raises(ConfigError, match="unknown OpenCV backend"):
        OpenCVCamera(0, INTRINSICS, backend="quicktime")
    with pytest.raises(ConfigError, match="flush_frames"):
        OpenCVCamera(0, INTRINSICS, flush_frames=-1)


def test_each_frame_reports_the_settings_the_device_reads_back(dev):
    with OpenCVCamera(0, INTRINSICS, timeout=0.2, exposure=120.0) as cam:
        first = cam.grab()
        dev.captures[0].props[cv2.CAP_PROP_EXPOSURE] = 180.0  # the driver changed it under us
        second = cam.grab()
    assert first.settings == {"exposure": 120.0, "gain": 4.0, "white_balance_k": 4600.0}
    assert second.settings["exposure"] == 180.0
