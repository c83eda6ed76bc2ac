"""What the camera reported about each frame (settings, its own time stamp and frame counter)
goes into the view event and comes back on the View; a malformed report loses only itself."""

from __future__ import annotations

import numpy as np

from armstereo import camera_settings
from armstereo.devices import Frame
from armstereo.recording import Recording, RecordingWriter
from tests.support.recordings import JOINTS, T0_NS, small_intrinsics


def write(path, frames, monkeypatch=None, bad_view=None):
    with RecordingWriter(path, metadata={}) as w:
        w.write_calibration(small_intrinsics(), T0_NS)
        for k, frame in enumerate(frames):
            if k == bad_view:
                monkeypatch.setattr(camera_settings, "view_event_fields",
                                    lambda f: {"camera_settings": {"exposure": "bright"},
                                               "device_frame": 3})
            w.write_view(k, frame, np.zeros(6), JOINTS, np.eye(4), np.eye(4), settle_s=0.0)


def test_the_camera_report_round_trips(tmp_path):
    img = np.zeros((32, 48, 3), np.uint8)
    frames = [Frame(img, T0_NS + 1, settings={"exposure_us": 800.0, "gain_db": 2.5,
                                              "balance_ratio": [1.4, 1.0, 1.7]},
                    device_timestamp_ns=123_456_789_000, device_frame=41),
              Frame(img, T0_NS + 2)]
    write(tmp_path / "r.mcap", frames)
    rec = Recording.open(tmp_path / "r.mcap")
    first, second = rec.view(0), rec.view(1)
    assert first.camera_settings == {"exposure_us": 800.0, "gain_db": 2.5,
                                     "balance_ratio": [1.4, 1.0, 1.7]}
    assert (first.device_timestamp_ns, first.device_frame) == (123_456_789_000, 41)
    assert (second.camera_settings, second.device_timestamp_ns, second.device_frame) == \
        (None, None, None)
    assert rec.warnings == []


def test_a_malformed_report_is_dropped_and_said_the_view_kept(tmp_path, monkeypatch):
    img = np.zeros((32, 48, 3), np.uint8)
    write(tmp_path / "m.mcap", [Frame(img, T0_NS + 1), Frame(img, T0_NS + 2)], monkeypatch,
          bad_view=1)
    rec = Recording.open(tmp_path / "m.mcap")
    assert [v.index for v in rec.views] == [0, 1] and rec.view(1).camera_settings is None
    assert any("camera report could not be decoded" in w and "exposure must be finite" in w
               for w in rec.warnings), rec.warnings
