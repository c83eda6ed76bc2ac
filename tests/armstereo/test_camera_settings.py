"""Camera settings per frame: validation, the view-event keys, and when two views differ by
more than the matcher tolerates (brightness from exposure and gain together, white balance
relative to green, gamma)."""

from __future__ import annotations

import numpy as np
import pytest

from armstereo import camera_settings as C
from armstereo.errors import RecordingError
from armstereo.frame import Frame


def test_validate_keeps_numbers_and_lists_and_refuses_the_rest():
    got = C.validate({"exposure_us": np.float32(1000), "balance_ratio": (1.5, 1, 1.25)})
    assert got == {"exposure_us": 1000.0, "balance_ratio": [1.5, 1.0, 1.25]}
    assert C.validate(None) is None
    for bad, message in (({"shutter": 1.0}, "unknown setting 'shutter'"),
                         ({"gain": float("nan")}, "gain must be finite"),
                         ({"gain": True}, "gain must be finite"),
                         ({"balance_ratio": []}, "balance_ratio must be finite")):
        with pytest.raises(RecordingError, match=message):
            C.validate(bad)


def test_view_event_fields_carry_only_what_the_camera_reported():
    img = np.zeros((2, 2), np.uint8)
    assert C.view_event_fields(Frame(img, 5)) == {}
    full = Frame(img, 5, settings={"gain_db": 3}, device_timestamp_ns=np.int64(7),
                 device_frame=2)
    assert C.view_event_fields(full) == {"camera_settings": {"gain_db": 3.0},
                                         "device_timestamp_ns": 7, "device_frame": 2}
    with pytest.raises(RecordingError, match="device_frame must be an integer >= 0"):
        C.view_event_fields(Frame(img, 5, device_frame=-1))


def by_what(diffs):
    return {d.what: d for d in diffs}


def test_brightness_combines_exposure_and_gain():
    same = C.compare({"exposure_us": 1000, "gain_db": 6.0}, {"exposure_us": 1000, "gain_db": 6.0})
    assert [d.relative for d in same] == [0.0] and not same[0].too_large
    # twice the exposure at 6.02 dB less gain is the same image
    traded = by_what(C.compare({"exposure_us": 1000, "gain_db": 6.0206},
                               {"exposure_us": 2000, "gain_db": 0.0}))
    assert traded["brightness"].relative == pytest.approx(0.0, abs=1e-4)
    drift = by_what(C.compare({"exposure": 156, "gain": 64}, {"exposure": 160, "gain": 64}))
    assert drift["brightness"].relative == pytest.approx(4 / 156)
    assert drift["brightness"].too_large
    assert "exposure 156 vs 160" in drift["brightness"].describe()


def test_white_balance_is_the_colour_cast_not_the_level():
    level = by_what(C.compare({"balance_ratio": [1.5, 1.0, 1.2]},
                              {"balance_ratio": [3.0, 2.0, 2.4]}))
    assert level["white balance"].relative == pytest.approx(0.0)
    cast = by_what(C.compare({"balance_ratio": [1.5, 1.0, 1.2]},
                             {"balance_ratio": [1.5, 1.0, 1.23]}))
    assert cast["white balance"].relative == pytest.approx(0.03 / 1.23)
    kelvin = by_what(C.compare({"white_balance_k": 4600}, {"white_balance_k": 4610}))
    assert kelvin["white balance"].relative == pytest.approx(10 / 4610)
    assert not kelvin["white balance"].too_large  # 0.22 %: within 0.25 %


def test_tolerance_edges_and_missing_reports():
    at = C.BRIGHTNESS_TOLERANCE
    assert not by_what(C.compare({"exposure": 1.0}, {"exposure": 1.0 + at * 0.99}))[
        "brightness"].too_large
    assert by_what(C.compare({"exposure": 1.0}, {"exposure": 1.0 + at * 1.5}))[
        "brightness"].too_large
    assert by_what(C.compare({"gamma": 1.0}, {"gamma": 1.01}))["gamma"].too_large
    assert C.compare(None, {"exposure": 1.0}) == [] and C.compare({"gain": 1}, {}) == []
    assert C.compare({"exposure_us": 10.0}, {"gain_db": 1.0}) == []  # nothing in common
