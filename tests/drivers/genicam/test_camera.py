"""GenICamCamera against a real GenTL producer that simulates cameras (viky.cti, see
conftest.py): opening by serial and index, pixel formats converted from the producer's own
payloads, the size set, fresh frames without a trigger, and the one-line errors for a missing
producer or extra, an unknown serial, a camera in use, a format or a feature it lacks."""

from __future__ import annotations

import sys

import numpy as np
import pytest

from armstereo import backends
from armstereo.camera_model import Intrinsics
from armstereo.clock import SimClock
from armstereo.errors import ConfigError, ConnectionFailed
from drivers.genicam.camera import GenICamCamera
from drivers.genicam.producer import DeviceEntry, find

INTR = Intrinsics(640, 480, np.array([[600.0, 0, 319.5], [0, 600.0, 239.5], [0, 0, 1]]))
BALL_BGR = {"0": (0, 0, 255), "1": (0, 255, 0), "2": (255, 0, 0)}  # red, green, blue balls


def camera(viky, device="0", **kw) -> GenICamCamera:
    return GenICamCamera(device, kw.pop("intrinsics", INTR), cti=viky, clock=SimClock(), **kw)


@pytest.mark.parametrize("serial", ["0", "2"])
def test_frames_are_the_cameras_colour_images_at_the_mount_size(viky, serial):
    with camera(viky, serial) as cam:
        frame = cam.grab()
        meta = cam.recording_metadata()
    img = frame.image
    assert img.shape == (480, 640, 3) and img.dtype == np.uint8
    colours = {tuple(c) for c in np.unique(img.reshape(-1, 3), axis=0)}
    # white with one ball: the RGBa8 payload came out as BGR in the right channel order
    assert colours == {(255, 255, 255), BALL_BGR[serial]}
    assert meta["camera_serial"] == serial and meta["camera_model"] == "Viky"
    assert meta["camera_pixel_format"] == "RGBa8" and meta["camera_trigger"] == "none"
    assert meta["camera_missing_features"] == "ExposureTime,Gain,BalanceRatio,Gamma"
    # viky keeps no buffer time stamps: none is invented; its frame counter is recorded
    assert frame.device_timestamp_ns is None and frame.device_frame is not None
    assert frame.settings is None


def test_mono8_is_delivered_grey(viky):
    with camera(viky, "1", pixel_format="Mono8") as cam:
        img = cam.grab().image
    assert img.shape == (480, 640) and img.dtype == np.uint8
    assert (img == 255).mean() > 0.9 and img.min() < 255  # white, and a darker ball


def test_a_serial_wins_over_an_index_and_an_index_is_the_fallback():
    entries = [DeviceEntry(0, "SN7", "V", "M", "id0", "", "ready"),
               DeviceEntry(1, "0", "V", "M", "id1", "left", "ready")]
    assert find(entries, "0", ("p.cti",)).index == 1  # serial "0" is camera 1
    assert find(entries, "1", ("p.cti",)).serial == "0"  # no serial "1": index 1
    assert find(entries, "left", ("p.cti",)).index == 1  # the user-defined name too
    with pytest.raises(ConnectionFailed, match="serial or index '2'"):
        find(entries, "2", ("p.cti",))


def test_each_grab_restarts_acquisition_so_no_frame_comes_from_a_buffer(viky):
    with GenICamCamera("0", INTR, cti=viky) as cam:  # the real clock
        first = cam.grab()
        assert not cam._ia.is_acquiring()  # stopped between shots: nothing piles up
        second = cam.grab()
    assert first.device_frame == second.device_frame  # each the first frame of its own start
    assert second.timestamp_ns > first.timestamp_ns


def test_an_unknown_serial_lists_the_cameras_found(viky):
    with pytest.raises(ConnectionFailed, match=r"no GenICam camera with serial or index 'SN9' "
                                               r"through viky.cti \(cameras found: 0: serial "
                                               r"'0' Machine Vision Games Ltd. Viky; 1: "):
        camera(viky, "SN9").connect()


def test_a_camera_already_open_is_refused_and_stays_usable(viky):
    with camera(viky, "2") as first:
        with pytest.raises(ConnectionFailed, match="is in use"):
            camera(viky, "2").connect()
        assert first.grab().image.shape == (480, 640, 3)


def test_a_format_or_feature_the_camera_lacks_is_a_config_error(viky):
    with pytest.raises(ConfigError, match=r"does not offer pixel format 'RGB8' \(it offers: "
                                          r"RGBa8, Mono8\)"):
        camera(viky, pixel_format="RGB8").connect()
    with pytest.raises(ConfigError, match="has no ExposureTime feature .* --exposure-us"):
        camera(viky, exposure_us=5000.0).connect()
    with pytest.raises(ConfigError, match="cannot be triggered by software"):
        camera(viky, trigger="software").connect()
    big = INTR.scaled(1280, 960)
    with pytest.raises(ConfigError, match=r"cannot deliver 1280x960 images \(Width takes "
                                          r"100\.\.800"):
        camera(viky, intrinsics=big).connect()


def test_a_missing_producer_is_a_config_error(tmp_path, monkeypatch):
    monkeypatch.delenv("GENICAM_GENTL64_PATH", raising=False)
    with pytest.raises(ConfigError, match="no GenTL producer: pass --cti"):
        camera(None).connect()
    monkeypatch.setenv("GENICAM_GENTL64_PATH", str(tmp_path))
    with pytest.raises(ConfigError, match="holds none"):
        camera(None).connect()
    with pytest.raises(ConfigError, match="no such GenTL producer file"):
        camera(str(tmp_path / "vendor.cti")).connect()
    bogus = tmp_path / "bogus.cti"
    bogus.write_text("not a shared library")
    with pytest.raises(ConfigError, match="is not a loadable GenTL producer"):
        camera(str(bogus)).connect()


def test_the_producer_folder_convention_finds_it(viky, monkeypatch):
    from pathlib import Path

    monkeypatch.setenv("GENICAM_GENTL64_PATH", str(Path(viky).parent))
    with camera(None, "1") as cam:
        assert cam.grab().image.shape == (480, 640, 3)


def test_a_missing_extra_is_named_with_its_pip_command(monkeypatch):
    monkeypatch.setitem(sys.modules, "harvesters", None)
    with pytest.raises(ConfigError, match=r"pip install 'armstereo\[genicam\]' \(harvesters is "
                                          r"not installed\)"):
        backends.camera_config("genicam:0")
