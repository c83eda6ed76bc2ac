"""The vignetting model: its values, its mount-file section, its removal."""

from __future__ import annotations

import tomllib

import numpy as np
import pytest

from armstereo.errors import ConfigError
from armstereo.photometric.vignetting import Vignetting, devignette

MODEL = Vignetting(640, 480, (322.0, 236.5), (-0.15, -0.08, 0.01))


def test_gain_is_one_at_the_centre_and_falls_radially():
    assert MODEL.gain(np.array(322.0), np.array(236.5)) == pytest.approx(1.0)
    r = MODEL.radius
    assert MODEL.gain(np.array(322.0 + r), np.array(236.5)) == pytest.approx(1 - 0.15 - 0.08
                                                                            + 0.01)
    corners = MODEL.corner_gains()
    assert np.all(corners < 0.8) and np.ptp(corners) < 0.02  # centre near the middle
    assert MODEL.gain_map().shape == (480, 640) and MODEL.gain_map().dtype == np.float32


def test_toml_section_round_trips_exactly():
    doc = tomllib.loads("\n".join(MODEL.toml_lines()))
    assert Vignetting.from_dict(doc["vignetting"], 640, 480) == MODEL
    short = Vignetting.from_dict({"k": [-0.2]}, 640, 480)  # missing terms are zero
    assert short.k == (-0.2, 0.0, 0.0) and short.center == (319.5, 239.5)


@pytest.mark.parametrize("doc,text", [
    ({}, "needs k"),
    ({"k": ["a"]}, "must be numbers"),
    ({"k": [-0.9, -0.9]}, "a lens's fall-off"),
    ({"k": [0.0, 0.0, 0.0, 0.1]}, "k = [k1, k2, k3]"),
])
def test_bad_sections_are_config_errors(doc, text):
    with pytest.raises(ConfigError, match=text.replace("[", r"\[").replace("]", r"\]")):
        Vignetting.from_dict(doc, 640, 480)


def test_devignette_undoes_the_fall_off_and_checks_the_size():
    flat = np.full((480, 640, 3), 180, np.uint8)
    dark = np.rint(flat * MODEL.gain_map()[..., None]).astype(np.uint8)
    back = devignette(dark, MODEL)
    assert np.abs(back.astype(int) - 180).max() <= 1
    grey = devignette(dark[..., 0], MODEL)
    assert grey.shape == (480, 640) and np.abs(grey.astype(int) - 180).max() <= 1
    with pytest.raises(ConfigError, match="640x480"):
        devignette(np.zeros((240, 320), np.uint8), MODEL)
