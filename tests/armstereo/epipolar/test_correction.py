"""Fitting the camera offset D from matches alone (no images): what one pair can and cannot
tell."""

from __future__ import annotations

import numpy as np
import pytest

from armstereo.epipolar.correction import CameraCorrection, fit_camera_correction
from armstereo.transforms import make_T, rotvec_to_matrix

from .synthetic import K

T1 = make_T(rotvec_to_matrix([0.3, -0.2, 0.1]), [0.4, -0.1, 0.6])  # recorded, base frame


def observe(T_cam1_cam2, D, noise=0.05, seed=0):
    """Matches of points 0.4-0.8 m ahead seen by the TRUE cameras T_i @ D."""
    rng = np.random.default_rng(seed)
    T2 = T1 @ T_cam1_cam2
    p_cam = np.c_[rng.uniform(-0.25, 0.25, 400), rng.uniform(-0.2, 0.2, 400),
                  rng.uniform(0.4, 0.8, 400)]
    p = p_cam @ (T1 @ D)[:3, :3].T + (T1 @ D)[:3, 3]
    xs = []
    for T in (T1 @ D, T2 @ D):
        pc = (p - T[:3, 3]) @ T[:3, :3]
        h = pc @ K.T
        xs.append(h[:, :2] / h[:, 2:] + rng.normal(0, noise, (len(p), 2)))
    return xs[0], xs[1], T2


def fit(T_cam1_cam2, D):
    x1, x2, T2 = observe(T_cam1_cam2, D)
    return fit_camera_correction(x1, x2, K, T1, K, T2)


def test_no_offset_gives_a_zero_correction():
    c = fit(make_T(rotvec_to_matrix([0.1, 0.3, 0.2]), [0.1, 0.02, 0.03]), np.eye(4))
    assert np.all(np.abs(c.rotation_deg) < 0.05) and np.all(np.abs(c.translation_mm) < 0.5)
    assert c.describe() == [] or all("cannot see" in s for s in c.describe())


def test_sideways_pair_recovers_yaw_and_roll_but_no_translation():
    D = make_T(rotvec_to_matrix(np.radians([0.0, 0.7, -0.5])), [0.004, 0.0, 0.0])
    c = fit(make_T(np.eye(3), [0.1, 0.0, 0.0]), D)
    assert list(c.rotation_determined) == [False, True, True]
    assert not c.translation_determined.any()
    np.testing.assert_allclose(c.rotation_deg[1:], [0.7, -0.5], atol=0.05)
    text = " ".join(c.describe())
    assert "further right" in text and "anticlockwise" in text
    assert "translation along camera x" in text  # named as invisible


def test_turned_pair_sees_a_translation_offset():
    """With the wrist tilted between the views, a forward offset changes the relative motion."""
    D = make_T(np.eye(3), [0.0, 0.0, 0.005])
    c = fit(make_T(rotvec_to_matrix([np.radians(20.0), 0.0, 0.0]), [0.08, 0.0, 0.0]), D)
    assert c.translation_determined[2]
    assert c.translation_mm[2] == pytest.approx(5.0, abs=0.5)
    assert c.median_sampson_after_px < 0.1


def test_description_signs():
    base = dict(rotation_sigma_deg=np.full(3, 0.01), translation_sigma_mm=np.full(3, 0.1),
                median_sampson_after_px=0.1)
    c = CameraCorrection(np.array([0.5, -0.8, 0.0]), np.array([0.0, -2.0, 0.0]), **base)
    text = c.describe()
    assert "the camera looks 0.50 deg further up than the mount says (+-0.01)" in text
    assert "the camera looks 0.80 deg further left than the mount says (+-0.01)" in text
    assert "the camera sits 2.0 mm further up than the mount says (+-0.1)" in text
    assert len(text) == 3  # zero components are not mentioned, nothing is hidden
    np.testing.assert_allclose(c.T_camrecorded_camtrue[:3, 3], [0, -0.002, 0])
