"""The predicted hand-eye error: expected magnitudes of a Gaussian error from its covariance."""

from __future__ import annotations

import math

import numpy as np
import pytest

from armstereo.calibration.prediction import (
    expected_norm,
    jackknife_covariance,
    predicted_error,
)


@pytest.mark.parametrize("sigmas, expected", [
    ((1.0, 1.0, 1.0), 2.0 * math.sqrt(2.0 / math.pi)),  # Maxwell: mean of chi_3
    ((1.0, 0.0, 0.0), math.sqrt(2.0 / math.pi)),  # half-normal
    ((1.0, 1.0, 0.0), math.sqrt(math.pi / 2.0)),  # Rayleigh
])
def test_expected_norm_matches_the_chi_limits(sigmas, expected):
    assert expected_norm(np.diag(np.square(sigmas)) * 4.0) == pytest.approx(2.0 * expected,
                                                                            rel=1e-3)


def test_expected_norm_of_a_correlated_covariance_matches_sampling():
    A = np.array([[2.0, 0.3, -0.1], [0.0, 0.7, 0.4], [0.0, 0.0, 0.2]])
    C = A @ A.T
    e = np.random.default_rng(1).standard_normal((400_000, 3)) @ np.linalg.cholesky(C).T
    assert expected_norm(C) == pytest.approx(np.mean(np.linalg.norm(e, axis=1)), rel=5e-3)


def test_predicted_error_reads_rotation_then_translation():
    C = np.diag([math.radians(0.01) ** 2] * 3 + [1e-4 ** 2, 1e-4 ** 2, 3e-4 ** 2])
    p = predicted_error(C, "test")
    assert p["rms_translation_m"] == pytest.approx(math.sqrt(11) * 1e-4)
    assert p["rms_rotation_deg"] == pytest.approx(math.sqrt(3) * 0.01)
    assert p["rotation_deg"] == pytest.approx(0.01 * 2.0 * math.sqrt(2.0 / math.pi), rel=1e-3)
    # the expected size lies below the RMS (Jensen), by more when one axis dominates
    assert 0.8 * p["rms_translation_m"] < p["translation_m"] < p["rms_translation_m"]
    assert p["translation_sigma_m"] == pytest.approx([1e-4, 1e-4, 3e-4])
    assert p["basis"] == "test"


def test_jackknife_covariance_is_diagonal_in_the_chart_order():
    C = jackknife_covariance(np.array([1e-4, 2e-4, 3e-4]), np.array([0.01, 0.02, 0.03]))
    np.testing.assert_allclose(np.sqrt(np.diag(C)),
                               np.r_[np.radians([0.01, 0.02, 0.03]), 1e-4, 2e-4, 3e-4])
    assert np.count_nonzero(C - np.diag(np.diag(C))) == 0
