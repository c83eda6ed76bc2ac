"""OpenCV's closed-form hand-eye methods, motion pairs and the rotation diversity checks."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from armstereo.calibration.checks import CalibrationInputError
from armstereo.calibration.handeye import (
    METHODS,
    check_diversity,
    closed_form_all,
    closed_form_views,
    motion_diversity,
    motion_pairs,
    solve_hand_eye,
)
from armstereo.calibration.poses import exp6, pose_difference, rotmat, rotvec
from armstereo.transforms import invert, make_T

X_TRUE = make_T(rotmat([0.02, -0.03, 1.2]), [0.01, -0.07, 0.045])  # T_flange_camera
B_TRUE = make_T(rotmat([3.1, 0.05, 0.2]), [-0.5, -0.15, 0.02])  # T_base_board


def _flanges(rotations: list[np.ndarray], rng: np.random.Generator) -> list[np.ndarray]:
    """Flange poses rotated (rotation vectors, flange frame) about a start pose, moved a bit."""
    F0 = make_T(rotmat([math.pi, 0.0, 0.0]), [-0.49, -0.13, 0.49])
    return [F0 @ make_T(rotmat(w), rng.normal(size=3) * 0.05) for w in rotations]


def _cameras(flanges, noise_rot=0.0, noise_t=0.0, rng=None):
    out = []
    for F in flanges:
        T = invert(F @ X_TRUE) @ B_TRUE
        if noise_rot or noise_t:
            T = exp6(np.concatenate([rng.normal(size=3) * noise_rot,
                                     rng.normal(size=3) * noise_t])) @ T
        out.append(T)
    return out


def _diverse(n: int, rng) -> list[np.ndarray]:
    return [rng.normal(size=3) * 0.3 for _ in range(n)]


@pytest.mark.parametrize("method", list(METHODS))
def test_every_method_recovers_the_hand_eye_from_exact_motions(method):
    rng = np.random.default_rng(0)
    F = _flanges(_diverse(8, rng), rng)
    X = solve_hand_eye(F, _cameras(F), method)
    dt, dr = pose_difference(X, X_TRUE)
    assert dt < 1e-6 and dr < 1e-5


def test_method_is_passed_by_keyword():
    """Positionally OpenCV would take the method for an output and run Tsai for all."""
    rng = np.random.default_rng(1)
    F = _flanges(_diverse(8, rng), rng)
    C = _cameras(F, 0.002, 0.001, rng)
    results = {m: solve_hand_eye(F, C, m) for m in METHODS}
    park = cv2.calibrateHandEye([f[:3, :3] for f in F], [f[:3, 3] for f in F],
                                [c[:3, :3] for c in C], [c[:3, 3] for c in C],
                                method=cv2.CALIB_HAND_EYE_PARK)
    np.testing.assert_allclose(results["park"][:3, 3], park[1].reshape(3), atol=1e-12)
    assert not np.allclose(results["park"], results["tsai"], atol=1e-9)


def test_closed_form_all_reports_residuals_for_every_method():
    rng = np.random.default_rng(2)
    F = _flanges(_diverse(10, rng), rng)
    out = closed_form_all(F, _cameras(F, 0.0005, 0.0002, rng))
    assert set(out) == set(METHODS)
    for est in out.values():
        dt, dr = pose_difference(est.T_flange_camera, X_TRUE)
        assert dt < 0.005 and dr < 0.2
        assert 0 < est.residual_rotation_deg < 0.5 and 0 < est.residual_translation_m < 0.005


def test_views_in_near_half_turn_pairs_are_left_out_of_the_closed_form():
    rng = np.random.default_rng(3)
    rots = _diverse(6, rng)
    # the last view is view 0 turned by 175 deg about the flange's z axis
    rots.append(rotvec(rotmat(rots[0]) @ rotmat([0.0, 0.0, math.radians(175.0)])))
    F = _flanges(rots, rng)
    pairs = motion_pairs(F, _cameras(F))
    bad = [(p.i, p.j) for p in pairs if not p.usable]
    assert (0, 6) in bad
    keep = closed_form_views(pairs, len(F))
    assert all(not (i in keep and j in keep) for i, j in bad)
    assert len(keep) >= len(F) - len(bad)


def test_axis_spread_of_two_perpendicular_rotations_is_ninety_degrees():
    rng = np.random.default_rng(4)
    F = _flanges([np.zeros(3), np.array([0.5, 0, 0]), np.array([0, 0.5, 0])], rng)
    div = motion_diversity([p for p in motion_pairs(F, _cameras(F)) if p.i == 0])
    assert div.axis_spread_deg == pytest.approx(90.0, abs=1.0)


def test_rotations_about_parallel_axes_only_are_refused():
    rng = np.random.default_rng(5)
    F = _flanges([np.array([0.0, 0.0, a]) for a in np.radians([0, 30, -40, 70, 15, -60])], rng)
    div = motion_diversity(motion_pairs(F, _cameras(F)))
    assert div.axis_spread_deg < 1.0
    with pytest.raises(CalibrationInputError, match="parallel axes") as info:
        check_diversity(div)
    assert "second, non-parallel axis" in str(info.value)


def test_too_similar_views_are_refused_and_weak_diversity_warns():
    rng = np.random.default_rng(6)
    F = _flanges([rng.normal(size=3) * 0.04 for _ in range(8)], rng)
    with pytest.raises(CalibrationInputError, match="too similar"):
        check_diversity(motion_diversity(motion_pairs(F, _cameras(F))))
    F = _flanges([np.zeros(3), np.array([0.35, 0, 0]), np.array([0.3, 0.1, 0]),
                  np.array([-0.3, 0.06, 0.0])], rng)
    warnings = check_diversity(motion_diversity(motion_pairs(F, _cameras(F))))
    assert any("low rotation diversity" in w for w in warnings)
