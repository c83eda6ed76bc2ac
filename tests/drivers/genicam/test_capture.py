"""armstereo capture and calibrate on the mock arm with ``--camera genicam:...`` against the
simulating producer: the recording holds the camera's images and what it says about itself;
every way it can fail ends in one line and exit 2 or 4."""

from __future__ import annotations

import contextlib
import io
import sys

import numpy as np
import pytest

from armstereo.cli.main import main
from armstereo.recording import Recording


def run(*argv: str) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main(["-q", *argv])
    return code, out.getvalue(), err.getvalue()


def test_capture_records_the_cameras_images_and_report(viky, tmp_path):
    out = tmp_path / "g.mcap"
    code, stdout, stderr = run("capture", "--camera", "genicam:1", "--cti", viky,
                               "--out", str(out))
    assert code == 0, stderr
    rec = Recording.open(out)
    assert len(rec) == 1 and rec.warnings == []
    meta = rec.metadata
    assert (meta["camera"], meta["camera_serial"], meta["camera_vendor"]) == \
        ("genicam:1", "1", "Machine Vision Games Ltd.")
    assert meta["camera_producer"].endswith("viky.cti") and meta["camera_trigger"] == "none"
    for view in rec.views:
        colours = {tuple(c) for c in np.unique(view.image.reshape(-1, 3), axis=0)}
        assert colours == {(255, 255, 255), (0, 255, 0)}  # viky's green ball on white
        assert view.device_frame is not None and view.device_timestamp_ns is None
    assert rec.calibration.size == (640, 480)


def test_calibrate_needs_a_board_the_simulator_cannot_show(viky, tmp_path):
    out = tmp_path / "cam.toml"
    code, _, stderr = run("calibrate", "--camera", "genicam:0", "--cti", viky,
                          "--board", "chessboard:17x12:0.016", "--out", str(out))
    assert code == 2 and stderr.count("\n") == 1, stderr
    assert "board" in stderr and not out.exists() and not out.with_suffix(".mcap").exists()


@pytest.mark.parametrize("extra,code,message", [
    (["--camera", "genicam:SN9"], 4, "no GenICam camera with serial or index 'SN9'"),
    (["--camera", "genicam:0", "--pixel-format", "YUV422Packed"], 2,
     "pixel format 'YUV422Packed' is not supported"),
    (["--camera", "genicam:0", "--pixel-format", "BGR8"], 2, "does not offer pixel format"),
    (["--camera", "genicam:0", "--gain-db", "3"], 2, "has no Gain feature"),
])
def test_camera_problems_end_in_one_line(viky, tmp_path, extra, code, message):
    out = tmp_path / "x.mcap"
    got, _, stderr = run("capture", "--cti", viky, *extra, "--out", str(out))
    assert got == code and message in stderr and stderr.count("\n") == 1, stderr
    assert "Traceback" not in stderr and not out.exists()


def test_no_producer_and_no_extra_end_in_one_line(tmp_path, monkeypatch):
    monkeypatch.delenv("GENICAM_GENTL64_PATH", raising=False)
    out = tmp_path / "x.mcap"
    code, _, stderr = run("capture", "--camera", "genicam:0", "--out", str(out))
    assert code == 2 and "no GenTL producer" in stderr and stderr.count("\n") == 1
    monkeypatch.setitem(sys.modules, "harvesters", None)
    code, _, stderr = run("capture", "--camera", "genicam:0", "--out", str(out))
    assert code == 2 and stderr.count("\n") == 1
    assert "needs the optional extra: pip install 'armstereo[genicam]'" in stderr
