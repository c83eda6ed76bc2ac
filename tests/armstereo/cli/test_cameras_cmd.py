"""armstereo cameras: what each installed backend sees (the mock always; GenICam cameras of
the simulating producer; the camera a RealSense recording was made with), and a missing extra
or producer said per backend, not as a failure."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

from armstereo.cli.main import main
from armstereo.mount import CameraMount
from tests.drivers.realsense.simulated import NAME, SERIAL, make_recording


def cameras(capsys, *args) -> dict:
    assert main(["cameras", "--json", *args]) == 0
    return {row["backend"]: row for row in json.loads(capsys.readouterr().out)["backends"]}


def viky() -> str:
    import genicam

    return str(Path(genicam.__file__).parent / "viky.cti")


def test_every_backend_answers_and_the_genicam_cameras_are_listed(capsys, monkeypatch):
    monkeypatch.delenv("GENICAM_GENTL64_PATH", raising=False)
    rows = cameras(capsys, "--cti", viky())
    assert list(rows) == ["mock", "opencv", "genicam", "realsense"]
    assert rows["mock"]["cameras"][0]["spec"] == "mock"
    genicam = rows["genicam"]["cameras"]
    assert [c["spec"] for c in genicam] == ["genicam:0", "genicam:1", "genicam:2"]
    assert genicam[0]["model"] == "Viky" and genicam[0]["status"] == "ready"
    assert genicam[0]["pixel_formats"] == ["RGBa8", "Mono8"]
    assert genicam[0]["modes"] == ["100..800 x 100..800 (now 400x400)"]
    assert rows["realsense"]["available"] and rows["realsense"]["cameras"] == []
    rows = cameras(capsys, "--backend", "genicam")
    assert not rows["genicam"]["available"]
    assert "no GenTL producer" in rows["genicam"]["reason"]


def test_a_recording_shows_its_camera_and_modes(capsys, tmp_path):
    intr = CameraMount.load(None).intrinsics
    bag = make_recording(tmp_path / "rs", [np.zeros((480, 640, 3), np.uint8)], intr)
    rows = cameras(capsys, "--backend", "realsense", "--realsense-playback", str(bag))
    (cam,) = rows["realsense"]["cameras"]
    assert cam["spec"] == f"realsense:{SERIAL}" and cam["model"] == NAME
    assert cam["modes"] == ["640x480@30 bgr8"] and str(bag) in cam["note"]


def test_missing_extras_are_named_in_text(capsys, monkeypatch):
    monkeypatch.setitem(sys.modules, "harvesters", None)
    monkeypatch.setitem(sys.modules, "pyrealsense2", None)
    assert main(["cameras"]) == 0
    out = capsys.readouterr().out
    assert "mock: 1 camera(s)\n  --camera mock" in out
    assert "genicam: unavailable: the genicam camera needs the optional extra: pip install " \
        "'armstereo[genicam]' (harvesters is not installed)" in out
    assert "realsense: unavailable: the realsense camera needs the optional extra" in out
    assert main(["cameras", "--backend", "mock", "--realsense-playback", "x.bag"]) == 2
