"""The RealSense settings logic on the SDK's own objects (a software device's colour sensor
with writable options, as a live camera has): locking, ranges, read-only options, the colour
mode, the factory intrinsics in OpenCV's model and the mount cross-check."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from armstereo.camera_model import Intrinsics
from armstereo.errors import ConfigError
from drivers.realsense import settings as S
from drivers.realsense.sdk import rs as load_rs
from tests.drivers.realsense.simulated import software_camera

K = np.array([[600.0, 0, 319.5], [0, 600.0, 239.5], [0, 0, 1]])
INTR = Intrinsics(640, 480, K)


@pytest.fixture(scope="module")
def rs():
    return load_rs()


def test_auto_modes_go_off_and_values_are_set_and_read_back(rs):
    _, sensor, _ = software_camera(INTR)
    rep = S.lock_options(rs, sensor, "cam", exposure=300.0, gain=None, white_balance=5000.0)
    assert rep.auto_off == ["enable_auto_exposure", "enable_auto_white_balance"]
    assert sensor.get_option(rs.option.enable_auto_exposure) == 0
    assert rep.settings == {"exposure": 300.0, "gain": 64.0, "white_balance_k": 5000.0}


def test_out_of_range_and_read_only_options_are_config_errors(rs):
    _, sensor, _ = software_camera(INTR)
    with pytest.raises(ConfigError, match=r"--white-balance 9000 is outside cam's "
                                          r"white_balance range 2800\.\.6500"):
        S.lock_options(rs, sensor, "cam", exposure=None, gain=None, white_balance=9000.0)
    dev = rs.software_device()
    bare = dev.add_sensor("RGB Camera")
    with pytest.raises(ConfigError, match="has no gain option"):
        S.lock_options(rs, bare, "cam", exposure=None, gain=3.0, white_balance=None)
    bare.add_read_only_option(rs.option.exposure, 156.0)
    with pytest.raises(ConfigError, match="exposure is read-only .*--exposure 100"):
        S.lock_options(rs, bare, "cam", exposure=100.0, gain=None, white_balance=None)


def test_the_colour_mode_is_chosen_or_the_modes_are_listed(rs):
    _, sensor, _ = software_camera(INTR)
    profiles = S.colour_profiles(rs, sensor)
    chosen = S.choose_profile(rs, profiles, None, 30, (640, 480), "cam")
    assert S.mode_of(rs, chosen).label() == "640x480@30 bgr8"
    with pytest.raises(ConfigError, match=r"no 1280x720 colour mode at 30 fps \(modes: "
                                          r"640x480@30 bgr8\)"):
        S.choose_profile(rs, profiles, (1280, 720), 30, None, "cam")
    with pytest.raises(ConfigError, match="no colour mode at 60 fps"):
        S.choose_profile(rs, profiles, None, 60, None, "cam")


def rs_intrinsics(rs, model: str, coeffs):
    ri = rs.intrinsics()
    ri.width, ri.height, ri.fx, ri.fy, ri.ppx, ri.ppy = 640, 480, 610.0, 612.0, 321.0, 238.0
    ri.model, ri.coeffs = getattr(rs.distortion, model), list(coeffs)
    return ri


def test_brown_conrady_is_opencvs_model(rs):
    coeffs = [0.12, -0.25, 0.001, -0.0005, 0.08]
    intr, note = S.to_intrinsics(rs, rs_intrinsics(rs, "brown_conrady", coeffs))
    np.testing.assert_allclose(intr.dist, coeffs, rtol=1e-6)
    assert intr.K[0, 0] == 610.0 and intr.K[1, 2] == 238.0 and "brown_conrady" in note
    # OpenCV projects a ray exactly as the SDK's own projection does
    ri = rs_intrinsics(rs, "brown_conrady", coeffs)
    point = [0.21, -0.13, 1.0]
    sdk_px = rs.rs2_project_point_to_pixel(ri, point)
    cv_px, _ = cv2.projectPoints(np.array([point]), np.zeros(3), np.zeros(3), intr.K, intr.dist)
    np.testing.assert_allclose(cv_px.ravel(), sdk_px, atol=1e-3)


def test_inverse_brown_conrady_is_fitted_to_opencvs_model(rs):
    ri = rs_intrinsics(rs, "inverse_brown_conrady", [-0.05, 0.06, 0.0008, -0.0004, -0.02])
    intr, note = S.to_intrinsics(rs, ri)
    assert "fitted" in note
    # a pixel the SDK deprojects (its inverse model) projects back there through OpenCV
    for px in ([5.0, 7.0], [320.0, 240.0], [630.0, 470.0], [100.0, 400.0]):
        ray = rs.rs2_deproject_pixel_to_point(ri, px, 1.0)
        back, _ = cv2.projectPoints(np.array([ray]), np.zeros(3), np.zeros(3), intr.K,
                                    intr.dist)
        assert np.hypot(*(back.ravel() - px)) < 0.05, px


def test_fisheye_models_are_refused(rs):
    with pytest.raises(ConfigError, match="kannala_brandt4 distortion model.*--mount"):
        S.to_intrinsics(rs, rs_intrinsics(rs, "kannala_brandt4", [0.1, 0, 0, 0, 0]))


def test_the_mount_is_checked_against_the_factory_calibration():
    device = Intrinsics(640, 480, K)
    assert S.cross_check(device, device) == []
    off = K.copy()
    off[0, 0] *= 1.03
    off[1, 2] += 9.0
    lines = S.cross_check(device, Intrinsics(640, 480, off))
    assert lines == ["fx 618.0 px in the mount, 600.0 px in the device (+3.0 %)",
                     "cy 248.5 px in the mount, 239.5 px in the device"]
