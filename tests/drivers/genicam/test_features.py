"""The SFNC settings logic on GenApi's own engine: a node map loaded from a device description
(tests/data/genicam/sfnc_camera.xml) whose values are read-only while their ``*Auto`` mode is
on, as on a camera. (The simulating producer the camera tests use has none of these features.)"""

from __future__ import annotations

from pathlib import Path

import pytest

from armstereo.errors import ConfigError
from drivers.genicam import features as F

XML = Path(__file__).parents[2] / "data" / "genicam" / "sfnc_camera.xml"


@pytest.fixture
def nm():
    from genicam.genapi import NodeMap

    node_map = NodeMap()
    node_map.load_xml_from_file(str(XML))
    return node_map


def test_auto_modes_go_off_and_the_asked_values_are_set_and_read_back(nm):
    assert not F.writable(F.node(nm, "ExposureTime"))  # locked while ExposureAuto runs
    rep = F.lock_settings(nm, "cam", exposure_us=8000.0, gain_db=6.0,
                          balance_ratio=(1.5, 1.0, 1.25), gamma=None)
    assert rep.locked == ["ExposureAuto", "GainAuto", "BalanceWhiteAuto"]
    assert nm.ExposureAuto.value == "Off" and nm.GainAuto.value == "Off"
    assert rep.settings == {"exposure_us": 8000.0, "gain_db": 6.0,
                            "balance_ratio": [1.5, 1.0, 1.25], "gamma": 1.0}
    assert rep.missing == [] and rep.notes == []


def test_what_nobody_asked_for_is_kept_and_locked(nm):
    rep = F.lock_settings(nm, "cam", exposure_us=None, gain_db=None, balance_ratio=None,
                          gamma=None)
    assert rep.settings == {"exposure_us": 15000.0, "gain_db": 3.5,
                            "balance_ratio": [1.8, 1.0, 1.4], "gamma": 1.0}
    assert nm.BalanceWhiteAuto.value == "Off"


def test_gamma_is_enabled_when_set(nm):
    rep = F.lock_settings(nm, "cam", exposure_us=None, gain_db=None, balance_ratio=None,
                          gamma=0.8)
    assert nm.GammaEnable.value is True and rep.settings["gamma"] == pytest.approx(0.8)


def test_a_value_outside_the_range_names_flag_feature_and_range(nm):
    with pytest.raises(ConfigError, match=r"--exposure-us 5 is outside cam's ExposureTime range "
                                          r"20\.\.1e\+06 us"):
        F.lock_settings(nm, "cam", exposure_us=5.0, gain_db=None, balance_ratio=None,
                        gamma=None)
    with pytest.raises(ConfigError, match=r"--gain-db 30 is outside cam's Gain range 0\.\.24 dB"):
        F.lock_settings(nm, "cam", exposure_us=None, gain_db=30.0, balance_ratio=None,
                        gamma=None)


def test_the_software_trigger_is_armed_and_fired(nm):
    assert F.setup_trigger(nm, "auto", "cam") == "software"
    assert (nm.TriggerSelector.value, nm.TriggerMode.value, nm.TriggerSource.value) == \
        ("FrameStart", "On", "Software")
    assert nm.TriggerSoftwareCount.value == 0
    F.fire(nm, "cam")  # the command writes its CommandValue (1) to the node it drives
    assert nm.TriggerSoftwareCount.value == 1
    assert F.setup_trigger(nm, "off", "cam") == "none" and nm.TriggerMode.value == "Off"


def test_read_settings_names_units_from_the_nodes(nm):
    got = F.read_settings(nm, balance=False)
    assert got == {"exposure_us": 15000.0, "gain_db": 3.5, "gamma": 1.0}
