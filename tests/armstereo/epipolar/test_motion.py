"""Motion classes and the capture guard."""

from __future__ import annotations

import numpy as np
import pytest

from armstereo.camera_model import Intrinsics
from armstereo.epipolar.motion import classify_motion, require_stereo_motion
from armstereo.errors import PreflightError
from armstereo.transforms import make_T, rot_x, rot_y, rot_z

INTR = Intrinsics(640, 480, np.array([[600.0, 0, 319.5], [0, 600.0, 239.5], [0, 0, 1]]))
# a camera somewhere in base, looking down (as on the mock arm)
T1 = make_T(rot_z(0.4) @ rot_x(np.pi), [-0.45, -0.13, 0.55])


def moved(T_cam1_cam2: np.ndarray) -> np.ndarray:
    return T1 @ T_cam1_cam2


def test_sideways_translation_is_lateral_with_epipoles_at_infinity():
    r = classify_motion(T1, moved(make_T(np.eye(3), [0.08, 0, 0])), intrinsics1=INTR)
    assert r.kind == "lateral"
    assert r.baseline_m == pytest.approx(0.08)
    assert r.baseline_angle_deg == pytest.approx(90.0)
    np.testing.assert_allclose(r.direction_cam1, [1, 0, 0], atol=1e-12)
    assert r.epipole1_px is None and not r.epipole_in_image and not r.warnings


def test_forward_motion_puts_the_epipole_in_the_image():
    r = classify_motion(T1, moved(make_T(np.eye(3), [0.01, 0, 0.1])), intrinsics1=INTR)
    assert r.kind == "forward"
    assert r.epipole_in_image
    assert r.epipole1_px == pytest.approx((319.5 + 600 * 0.1, 239.5))
    assert "inside image 1" in r.warnings[0]


def test_rotation_only():
    r = classify_motion(T1, moved(make_T(rot_y(0.2), [0.001, 0, 0])), intrinsics1=INTR)
    assert r.kind == "rotation_only" and r.rotation_deg == pytest.approx(np.degrees(0.2))


def test_turned_and_moved_is_general():
    r = classify_motion(T1, moved(make_T(rot_y(0.3), [0.1, 0, 0.02])), intrinsics1=INTR)
    assert r.kind == "general"


def test_capture_guard_refuses_rotation_only_and_passes_warnings_on():
    with pytest.raises(PreflightError, match="pure rotation"):
        require_stereo_motion(T1, moved(make_T(rot_y(0.2), [0, 0, 0])), INTR)
    report = require_stereo_motion(T1, moved(make_T(np.eye(3), [0.0, 0.0, 0.1])), INTR)
    assert report.kind == "forward" and report.warnings
