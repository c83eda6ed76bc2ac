"""Fundamental-matrix estimators against synthetic correspondences with a known F."""

from __future__ import annotations

import numpy as np
import pytest

from armstereo.epipolar.errors import DegenerateError, EpipolarError
from armstereo.epipolar.fundamental import (
    METHODS,
    ROBUST_METHODS,
    eight_point,
    estimate_fundamental,
    fundamental_from_poses,
)
from armstereo.epipolar.metrics import sampson_distance
from armstereo.errors import StereoError
from armstereo.transforms import make_T, rot_x, rot_y, rot_z

from .synthetic import K, correspondences

# At 0.5 px noise on 200 points, the estimate's Sampson distance to the TRUE (noise-free)
# correspondences is about 0.1 px for a good estimator; 0.3 px leaves room for the weaker ones
# without letting a wrong matrix (tens of px) through.
TRUTH_TOLERANCE_PX = 0.3
NOISE_PX = 0.5


def true_F(c) -> np.ndarray:
    return fundamental_from_poses(K, K, np.eye(4), c.T_cam1_cam2)


def test_pose_implied_F_holds_exactly_for_projected_points():
    c = correspondences(noise=0.0)
    F = true_F(c)
    assert np.linalg.norm(F) == pytest.approx(1.0)
    assert np.linalg.matrix_rank(F, tol=1e-9) == 2
    assert np.max(sampson_distance(F, c.true1, c.true2)) < 1e-9


def test_pose_implied_F_is_frame_independent():
    c = correspondences(noise=0.0)
    T_base = make_T(rot_z(0.7) @ rot_x(-0.3), [1.0, -2.0, 0.5])  # any common frame
    F = fundamental_from_poses(K, K, T_base, T_base @ c.T_cam1_cam2)
    np.testing.assert_allclose(F, true_F(c), atol=1e-12)


@pytest.mark.parametrize("method", METHODS)
def test_each_estimator_recovers_F_at_half_a_pixel_of_noise(method):
    c = correspondences(noise=NOISE_PX, seed=1)
    F, mask = estimate_fundamental(c.x1, c.x2, method)
    assert F.shape == (3, 3) and mask.shape == (200,) and mask.dtype == bool
    assert np.linalg.matrix_rank(F, tol=1e-9) == 2
    assert np.mean(sampson_distance(F, c.true1, c.true2)) < TRUTH_TOLERANCE_PX
    # the observed points sit at about their noise level from the estimated lines
    assert np.median(sampson_distance(F, c.x1, c.x2)) < 2 * NOISE_PX
    assert mask.mean() > 0.85


@pytest.mark.parametrize("method", ROBUST_METHODS)
def test_robust_estimators_keep_F_with_30_percent_gross_outliers(method):
    c = correspondences(noise=NOISE_PX, outliers=0.3, seed=2)
    F, mask = estimate_fundamental(c.x1, c.x2, method)
    inl = c.inlier
    assert np.median(sampson_distance(F, c.x1[inl], c.x2[inl])) < 1.0
    assert mask[inl].mean() >= 0.85
    assert mask[~inl].mean() < 0.1  # outliers mostly rejected (a few land near their line)
    assert np.mean(sampson_distance(F, c.true1[inl], c.true2[inl])) < TRUTH_TOLERANCE_PX


def test_the_8_point_algorithm_breaks_on_outliers():
    """The control for the test above: without a robust loop 30 % outliers ruin F."""
    c = correspondences(noise=NOISE_PX, outliers=0.3, seed=2)
    F, _ = estimate_fundamental(c.x1, c.x2, "8point")
    assert np.mean(sampson_distance(F, c.true1, c.true2)) > 5.0


def test_noise_free_8_point_is_exact():
    c = correspondences(noise=0.0, seed=3)
    F = eight_point(c.x1, c.x2)
    np.testing.assert_allclose(F, true_F(c), atol=1e-8)


@pytest.mark.parametrize("method", METHODS)
def test_fewer_than_eight_matches_raise(method):
    c = correspondences(n=7, noise=0.0)
    with pytest.raises(DegenerateError, match="at least 8"):
        estimate_fundamental(c.x1, c.x2, method)


@pytest.mark.parametrize("method", METHODS)
def test_points_on_one_plane_raise(method):
    c = correspondences(noise=0.2, planar=True, seed=4)
    with pytest.raises(DegenerateError):
        estimate_fundamental(c.x1, c.x2, method)


@pytest.mark.parametrize("method", METHODS)
def test_a_camera_that_only_rotates_raises(method):
    c = correspondences(noise=0.2, seed=5, T_cam1_cam2=make_T(rot_y(0.1) @ rot_x(0.05),
                                                              [0, 0, 0]))
    with pytest.raises(DegenerateError):
        estimate_fundamental(c.x1, c.x2, method)


def test_rotation_only_is_refused_among_outliers_too():
    c = correspondences(noise=0.3, outliers=0.3, seed=6,
                        T_cam1_cam2=make_T(rot_y(0.12), [0, 0, 0]))
    with pytest.raises(DegenerateError, match="only rotated"):
        estimate_fundamental(c.x1, c.x2, "magsac")


def test_allow_degenerate_returns_a_matrix_that_fits_anyway():
    c = correspondences(noise=0.3, seed=7, T_cam1_cam2=make_T(rot_y(0.1), [0, 0, 0]))
    F, mask = estimate_fundamental(c.x1, c.x2, "magsac", allow_degenerate=True)
    assert mask.mean() > 0.8  # fits the points: which is why it has to be refused


def test_coincident_camera_centres_have_no_F():
    T = make_T(rot_x(0.3), [0.2, 0.1, 0.0])
    with pytest.raises(DegenerateError, match="coincide"):
        fundamental_from_poses(K, K, T, T @ make_T(rot_y(0.2), [0, 0, 0]))


@pytest.mark.parametrize("x1, x2, match", [
    (np.zeros((10, 3)), np.zeros((10, 2)), "shape"),
    (np.zeros((10, 2)), np.zeros((9, 2)), "10 points"),
    (np.full((10, 2), np.nan), np.zeros((10, 2)), "non-finite"),
])
def test_malformed_points_raise(x1, x2, match):
    with pytest.raises(EpipolarError, match=match):
        estimate_fundamental(x1, x2, "8point")


def test_unknown_method_and_bad_options_raise():
    c = correspondences()
    with pytest.raises(EpipolarError, match="unknown"):
        estimate_fundamental(c.x1, c.x2, "magic")
    with pytest.raises(EpipolarError, match="threshold"):
        estimate_fundamental(c.x1, c.x2, "ransac", threshold=0)
    with pytest.raises(EpipolarError, match="confidence"):
        estimate_fundamental(c.x1, c.x2, "ransac", confidence=1.0)


def test_errors_are_stereo_errors_with_exit_code_6():
    assert issubclass(DegenerateError, StereoError) and DegenerateError.exit_code == 6


def test_bad_poses_and_camera_matrices_raise():
    with pytest.raises(EpipolarError, match="rigid"):
        fundamental_from_poses(K, K, np.eye(4), np.diag([2.0, 1, 1, 1]))
    with pytest.raises(EpipolarError, match="camera matrix"):
        fundamental_from_poses(np.zeros((3, 3)), K, np.eye(4), make_T(np.eye(3), [1, 0, 0]))


def test_seeded_estimators_are_repeatable():
    c = correspondences(outliers=0.3, seed=8)
    for method in ("mlesac", "mapsac"):
        F1, m1 = estimate_fundamental(c.x1, c.x2, method, seed=3)
        F2, m2 = estimate_fundamental(c.x1, c.x2, method, seed=3)
        np.testing.assert_array_equal(F1, F2)
        np.testing.assert_array_equal(m1, m2)
