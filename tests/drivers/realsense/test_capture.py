"""armstereo capture and calibrate on the mock arm with ``--camera realsense:<serial>`` played
back from a recording: the mock camera's session is recorded through the SDK (a software
device and the SDK's recorder) and replayed shot for shot, so the new recording must hold
exactly the recorded camera's images, settings and time stamps, and calibrate must compute
what it computed from the mock camera."""

from __future__ import annotations

import contextlib
import io
import json
import tomllib

import numpy as np
import pytest

from armstereo.cli.main import main
from armstereo.mount import CameraMount
from armstereo.recording import Recording
from tests.drivers.realsense.simulated import SERIAL, make_recording

BOARD = "chessboard:17x12:0.016"
NOMINAL = CameraMount.load(None).intrinsics  # the "factory calibration" of the replayed camera


def run(*argv: str) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main(["-q", *argv])
    return code, out.getvalue(), err.getvalue()


def replay_of(rec: Recording, path, *, start_frame: bool, settings=None):
    """The views of ``rec`` as a RealSense recording (with the start image calibrate grabs
    before its first view, when ``start_frame``)."""
    images = [v.image for v in rec.views]
    if start_frame:
        images = [images[0], *images]
    return make_recording(path, images, NOMINAL, settings=settings)


def test_capture_replays_the_cameras_images_settings_and_time_stamps(tmp_path):
    code, _, err = run("capture", "--out", str(tmp_path / "mock.mcap"))
    assert code == 0, err
    mock = Recording.open(tmp_path / "mock.mcap")
    settings = [{"exposure": 156, "gain": 64, "white_balance_k": 4600},
                {"exposure": 162, "gain": 64, "white_balance_k": 4600}]  # auto exposure drifted
    bag = replay_of(mock, tmp_path / "session", start_frame=False, settings=settings)
    out = tmp_path / "rs.mcap"
    code, _, err = run("capture", "--camera", f"realsense:{SERIAL}", "--realsense-playback",
                       str(bag), "--out", str(out))
    assert code == 0, err
    rec = Recording.open(out)
    assert rec.warnings == [] and len(rec) == 1
    for got, want in zip(rec.views, mock.views, strict=True):
        np.testing.assert_array_equal(got.image, want.image)
    assert [v.camera_settings["exposure"] for v in rec.views] == [156.0, 162.0]
    assert [v.device_timestamp_ns for v in rec.views] == [5_000_000_000, 5_033_333_000]
    assert rec.metadata["camera_serial"] == SERIAL
    assert rec.metadata["camera_intrinsics_source"] == "device"
    # ... and check tells that the two views were not shot at the same exposure
    code, stdout, _ = run("check", str(out), "--json")
    pair = json.loads(stdout)["pairs"][0]
    assert code == 0 and pair["camera_settings"]["warnings"] == [
        "views 0 and 1: the two views differ in brightness by 3.8 % (exposure 156 vs 162, "
        "gain 64 vs 64; more than 0.25 % costs the matcher accuracy)"]


@pytest.mark.slow
def test_calibrate_from_a_replayed_session_computes_what_the_live_one_did(tmp_path):
    code, _, err = run("calibrate", "--board", BOARD, "--views", "6",
                       "--out", str(tmp_path / "mock.toml"))
    assert code == 0, err
    mock = Recording.open(tmp_path / "mock.mcap")
    bag = replay_of(mock, tmp_path / "session", start_frame=True)
    out = tmp_path / "rs.toml"
    code, _, err = run("calibrate", "--camera", f"realsense:{SERIAL}", "--realsense-playback",
                       str(bag), "--board", BOARD, "--views", "6", "--out", str(out))
    assert code == 0, err
    rec = Recording.open(out.with_suffix(".mcap"))
    assert len(rec.views) == len(mock.views) == 6
    for got, want in zip(rec.views, mock.views, strict=True):
        np.testing.assert_array_equal(got.image, want.image)
        np.testing.assert_allclose(got.joint_positions, want.joint_positions)
    assert [v.device_frame for v in rec.views] == list(range(1, 7))  # frame 0: the start image
    a = tomllib.loads((tmp_path / "mock.toml").read_text())
    b = tomllib.loads(out.read_text())
    np.testing.assert_allclose(b["camera"]["K"], a["camera"]["K"], rtol=1e-9)
    np.testing.assert_allclose(b["hand_eye"]["translation"], a["hand_eye"]["translation"],
                               atol=1e-9)


def test_a_wrong_serial_or_file_ends_in_one_line(tmp_path):
    bag = make_recording(tmp_path / "one", [np.zeros((480, 640, 3), np.uint8)], NOMINAL)
    for camera, playback, code, message in (
            ("realsense:999", str(bag), 4, f"is of RealSense '{SERIAL}', not '999'"),
            (f"realsense:{SERIAL}", str(tmp_path / "none.bag"), 2, "no such file"),
            ("realsense:999", None, 4, "no RealSense camera with serial '999'")):
        extra = [] if playback is None else ["--realsense-playback", playback]
        got, _, err = run("capture", "--camera", camera, *extra, "--out",
                          str(tmp_path / "x.mcap"))
        assert got == code and message in err and err.count("\n") == 1, err
        assert not (tmp_path / "x.mcap").exists()
