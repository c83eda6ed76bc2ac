"""RealSenseCamera on recordings played back through the SDK (made by the SDK's recorder from a
software device, tests/drivers/realsense/simulated.py), and live on a software device: frames
in order with their own settings and time stamps, the factory intrinsics, fresh frames, and
the one-line errors."""

from __future__ import annotations

import sys
import threading
import time

import numpy as np
import pytest

from armstereo import backends
from armstereo.camera_model import Intrinsics
from armstereo.errors import CameraTimeout, ConfigError, ConnectionFailed
from drivers.realsense.camera import RealSenseCamera
from drivers.realsense.sdk import rs as load_rs
from tests.drivers.realsense.simulated import (
    FRAME_PERIOD_MS,
    SERIAL,
    START_MS,
    make_recording,
    push,
    software_camera,
)

K = np.array([[604.0, 0, 322.0], [0, 605.0, 241.0], [0, 0, 1]])
DEVICE = Intrinsics(640, 480, K, np.array([0.1, -0.2, 0.001, 0.0005, 0.05]))
MOUNT = Intrinsics(640, 480, np.array([[600.0, 0, 319.5], [0, 600.0, 239.5], [0, 0, 1]]))


@pytest.fixture(scope="module")
def recording(tmp_path_factory):
    """Three frames of grey 10, 20, 30 shot at exposure 150, 151, 152."""
    images = [np.full((480, 640, 3), 10 * (k + 1), np.uint8) for k in range(3)]
    settings = [{"exposure": 150 + k, "gain": 32, "white_balance_k": 4500} for k in range(3)]
    return make_recording(tmp_path_factory.mktemp("rs") / "three", images, DEVICE,
                          settings=settings)


def test_a_playback_hands_over_its_frames_in_order_with_their_report(recording):
    cam = RealSenseCamera(SERIAL, MOUNT, playback=str(recording))
    with cam:
        frames = [cam.grab() for _ in range(3)]
        meta = cam.recording_metadata()
        with pytest.raises(CameraTimeout, match="no more frames"):
            cam.grab(timeout=0.5)
    assert [int(f.image.mean()) for f in frames] == [10, 20, 30]
    assert [f.settings for f in frames] == [
        {"exposure": 150.0 + k, "gain": 32.0, "white_balance_k": 4500.0} for k in range(3)]
    assert [f.device_frame for f in frames] == [0, 1, 2]
    assert [f.device_timestamp_ns for f in frames] == [
        round((START_MS + k * FRAME_PERIOD_MS) * 1000) * 1000 for k in range(3)]
    # the factory intrinsics, not the mount's
    np.testing.assert_allclose(cam.intrinsics.K, K)
    np.testing.assert_allclose(cam.intrinsics.dist, DEVICE.dist, rtol=1e-6)
    assert meta["camera_serial"] == SERIAL and meta["camera_mode"] == "640x480@30 bgr8"
    assert meta["camera_intrinsics_source"] == "device"


def test_the_mount_intrinsics_are_used_and_checked_when_asked(recording):
    cam = RealSenseCamera(SERIAL, MOUNT, playback=str(recording), intrinsics_source="mount")
    with cam:
        np.testing.assert_allclose(cam.intrinsics.K, MOUNT.K)
        disagreement = cam.recording_metadata()["camera_intrinsics_vs_mount"]
    assert disagreement == ""  # within 1 % and 5 px of the factory calibration
    far = Intrinsics(640, 480, MOUNT.K * [[1.05], [1.0], [1.0]])
    with RealSenseCamera(SERIAL, far, playback=str(recording), intrinsics_source="mount") as c:
        assert "fx 630.0 px in the mount, 604.0 px in the device (+4.3 %)" in \
            c.recording_metadata()["camera_intrinsics_vs_mount"]


def test_a_playback_of_another_camera_and_an_unknown_serial_are_refused(recording):
    with pytest.raises(ConnectionFailed, match=f"is of RealSense '{SERIAL}', not '111'"):
        RealSenseCamera("111", MOUNT, playback=str(recording)).connect()
    with pytest.raises(ConnectionFailed, match="no RealSense camera with serial '111' "
                                               r"\(found: none; "):
        RealSenseCamera("111", MOUNT).connect()  # no camera on this machine


def test_settings_cannot_be_changed_on_a_playback(recording):
    with pytest.raises(ConfigError, match="exposure is read-only .*playback"):
        RealSenseCamera(SERIAL, MOUNT, playback=str(recording), exposure=200.0).connect()


@pytest.mark.parametrize("host_clock", [False, True])
def test_a_live_camera_gives_a_frame_exposed_after_the_call(host_clock):
    """A software device streaming at 30 Hz, each frame arriving 20 ms after its exposure
    began (exposure and read-out), time stamped on its own clock or on the host's. The grab is
    called while frame 10 is being exposed: it must skip frames queued before and frame 10
    too, which arrives after the call but was exposing while "the arm still moved"."""
    rs = load_rs()
    dev, sensor, profile = software_camera(MOUNT, locked=False)
    cam = RealSenseCamera(SERIAL, MOUNT, device=dev, exposure=300.0)
    started, stop, exposing = {}, threading.Event(), threading.Event()

    def stream():
        k = 0
        while not stop.is_set():
            started[k] = time.time_ns()
            if k == 10:
                exposing.set()
            time.sleep(0.020)
            push(rs, sensor, profile, np.full((480, 640, 3), k % 250, np.uint8), k,
                 host_ms=started[k] / 1e6 if host_clock else None)
            k += 1
            time.sleep(FRAME_PERIOD_MS / 1000 - 0.020)

    with cam:
        assert cam.locked.auto_off == ["enable_auto_exposure", "enable_auto_white_balance"]
        assert sensor.get_option(rs.option.exposure) == 300.0
        thread = threading.Thread(target=stream, daemon=True)
        thread.start()
        try:
            assert exposing.wait(5.0)
            called = time.time_ns()
            frame = cam.grab(timeout=2.0)
        finally:
            stop.set()
            thread.join()
    assert started[10] < called
    assert frame.device_frame == 11 and started[11] >= called


def test_a_missing_extra_is_named_with_its_pip_command(monkeypatch):
    monkeypatch.setitem(sys.modules, "pyrealsense2", None)
    with pytest.raises(ConfigError, match=r"pip install 'armstereo\[realsense\]' "
                                          r"\(pyrealsense2 is not installed\)"):
        backends.camera_config("realsense:123")
