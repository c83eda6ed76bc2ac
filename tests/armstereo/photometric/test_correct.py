"""Photometric options as the entry points take them, the record, and a recording's model."""

from __future__ import annotations

import pytest

from armstereo.errors import ConfigError
from armstereo.mount import CameraMount
from armstereo.photometric.correct import (
    PhotometricOptions,
    as_options,
    for_recording,
    record,
    recorded_vignetting,
)
from armstereo.photometric.vignetting import Vignetting

MODEL = Vignetting(640, 480, (320.0, 240.0), (-0.2, -0.05, 0.0))


def test_true_false_and_choices():
    assert as_options(True) == PhotometricOptions()
    off = as_options(False)
    assert not off.vignetting and not off.exposure and as_options(None) == off
    assert PhotometricOptions.from_choice("exposure") == PhotometricOptions(vignetting=False)
    with pytest.raises(ConfigError, match="--photometric"):
        PhotometricOptions.from_choice("some")
    with pytest.raises(ConfigError):
        as_options("yes")
    with pytest.raises(ConfigError):
        PhotometricOptions(vignetting=1)


def test_the_model_is_used_only_when_asked_for_and_known():
    assert not PhotometricOptions().removes_vignetting  # no model known
    assert PhotometricOptions().with_model(MODEL).removes_vignetting
    assert not PhotometricOptions(vignetting=False).with_model(MODEL).removes_vignetting
    given = PhotometricOptions(model=MODEL)
    assert given.with_model(None) is given


def test_the_record_says_what_was_done():
    entry = record(PhotometricOptions(model=MODEL), [1.01, 0.99, 1.0])
    assert entry["vignetting"]["applied"] and entry["vignetting"]["model"]["k"][0] == -0.2
    assert entry["exposure"] == {"applied": True, "requested": True,
                                 "gains": [1.01, 0.99, 1.0]}
    still = record(PhotometricOptions(), [1.0005, 1.0, 0.9999])
    assert not still["exposure"]["applied"] and not still["vignetting"]["applied"]
    assert not record(PhotometricOptions.off(), None)["exposure"]["requested"]


def test_the_recorded_mount_file_carries_the_model():
    old = CameraMount.load(None).source  # an older mount file: no [vignetting]
    assert recorded_vignetting({"mount_toml": old}) is None
    new = old + "\n" + "\n".join(MODEL.toml_lines())
    assert recorded_vignetting({"mount_toml": new}) == MODEL
    assert for_recording(True, {"mount_toml": new}).removes_vignetting
    assert recorded_vignetting({"mount_toml": "[vignetting]\nk = 'x'"}) is None  # unreadable
    assert recorded_vignetting({}) is None
