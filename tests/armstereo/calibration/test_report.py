"""Quality numbers: jackknife, board pose spread, the error's effect on a scan, warnings."""

from __future__ import annotations

import math

import numpy as np
import pytest

from armstereo.calibration.poses import exp6
from armstereo.calibration.report import (
    _jackknife_se,
    arm_error_warnings,
    board_pose_spread,
    error_effects,
    plausibility_warnings,
    view_warnings,
)
from armstereo.camera_model import Intrinsics
from armstereo.transforms import invert, make_T

INTR = Intrinsics(640, 480, np.array([[600.0, 0, 319.5], [0, 600.0, 239.5], [0, 0, 1.0]]))


def test_jackknife_of_the_mean_is_the_standard_error_of_the_mean():
    rng = np.random.default_rng(0)
    data = rng.normal(size=(20, 3))
    loo_means = np.array([np.delete(data, i, axis=0).mean(axis=0) for i in range(20)])
    np.testing.assert_allclose(_jackknife_se(loo_means),
                               data.std(axis=0, ddof=1) / math.sqrt(20), rtol=1e-12)


def test_error_effects_follow_the_small_angle_rules():
    e = error_effects(0.0002, 0.1, 0.5, INTR)
    assert e["placement_m_per_deg"] == pytest.approx(0.5 * math.pi / 180)  # ~9 mm per degree
    assert e["placement_m_per_deg"] == pytest.approx(0.0087, abs=1e-4)
    assert e["view_width_m"] == pytest.approx(0.5 * 640 / 600)
    assert e["surface_tilt_m_per_deg"] == pytest.approx(e["view_width_m"] * math.pi / 180)
    assert e["placement_error_m"] == pytest.approx(0.0002 + 0.5 * math.radians(0.1))
    assert e["surface_tilt_m"] == pytest.approx(e["view_width_m"] * math.radians(0.1))


def test_board_pose_spread_is_zero_for_consistent_views_and_sees_noise():
    X = make_T(np.eye(3), [0.0, -0.07, 0.04])
    B = make_T(np.eye(3), [-0.5, -0.1, 0.0])
    rng = np.random.default_rng(1)
    F = [exp6(rng.normal(size=6) * 0.2) for _ in range(6)]
    C = [invert(f @ X) @ B for f in F]
    t, r = board_pose_spread(F, X, C)
    assert t < 1e-12 and r < 1e-6
    F_noisy = [f @ exp6([0, 0, 0, 0.001, 0, 0]) if i % 2 else f for i, f in enumerate(F)]
    t, _ = board_pose_spread(F_noisy, X, C)
    assert 0.0003 < t < 0.001


def test_warnings_fire_only_past_their_thresholds():
    assert arm_error_warnings(0.0001, 0.005, 0.45, 0.42) == []
    assert len(arm_error_warnings(0.0005, 0.005, 0.45, 0.42)) == 1
    assert len(arm_error_warnings(0.0001, 0.005, 1.2, 0.42)) == 1
    assert view_warnings(np.array([0.4, 0.42, 0.41, 2.0]), [0, 1, 2, 7])[0].startswith("view 7")
    assert plausibility_warnings(make_T(np.eye(3), [0.0, 0.0, 0.05])) == []
    assert "tool0" in plausibility_warnings(make_T(np.eye(3), [0.0, 0.0, 0.5]))[0]
