"""Exact values of the three error measures on a rectified rig, where they are simple."""

from __future__ import annotations

import numpy as np
import pytest

from armstereo.epipolar.errors import EpipolarError
from armstereo.epipolar.metrics import (
    optimal_correction,
    reprojection_error,
    sampson_distance,
    symmetric_epipolar_distance,
)

# Rectified pair: x2^T F x1 = y1 - y2, epipolar lines are the rows.
F_RECT = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])
X1 = np.array([[100.0, 50.0], [10.0, 300.0], [400.0, 7.0]])
DY = np.array([0.0, 1.0, -3.0])
X2 = X1 + np.c_[[-20.0, -5.0, -40.0], DY]


def test_sampson_distance_of_a_row_offset():
    # the smallest total displacement puts each point dy/2 towards the other: |dy|/sqrt(2)
    np.testing.assert_allclose(sampson_distance(F_RECT, X1, X2), np.abs(DY) / np.sqrt(2))


def test_symmetric_epipolar_distance_of_a_row_offset():
    np.testing.assert_allclose(symmetric_epipolar_distance(F_RECT, X1, X2), np.abs(DY))


def test_reprojection_error_after_optimal_triangulation():
    c1, c2 = optimal_correction(F_RECT, X1, X2)
    np.testing.assert_allclose(c1[:, 1], c2[:, 1], atol=1e-9)  # corrected pairs share a row
    np.testing.assert_allclose(c1[:, 1], X1[:, 1] + DY / 2, atol=1e-9)
    np.testing.assert_allclose(reprojection_error(F_RECT, X1, X2), np.abs(DY) / 2, atol=1e-9)


def test_measures_do_not_depend_on_the_scale_of_F():
    for fn in (sampson_distance, symmetric_epipolar_distance, reprojection_error):
        np.testing.assert_allclose(fn(-7.0 * F_RECT, X1, X2), fn(F_RECT, X1, X2), atol=1e-9)


def test_bad_input_raises():
    with pytest.raises(EpipolarError, match="3x3"):
        sampson_distance(np.eye(2), X1, X2)
    with pytest.raises(EpipolarError, match="points"):
        sampson_distance(F_RECT, X1, X2[:2])
