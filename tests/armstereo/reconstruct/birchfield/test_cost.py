"""Birchfield-Tomasi sampling-insensitive dissimilarity (docs/birchfield-tomasi.md §3, §10.1)."""

from __future__ import annotations

import numpy as np
import pytest

from armstereo.reconstruct.birchfield.common.cost import scanline_dissimilarity, variation_flags


def _rows(seed: int, n: int = 40):
    rng = np.random.default_rng(seed)
    return (rng.integers(0, 256, n).astype(np.uint8), rng.integers(0, 256, n).astype(np.uint8))


def test_hand_computed_cases():
    # right half-samples around pixel 1 of [0, 100, 0] are 50 and 50: interval [50, 100];
    # the left row [0, 0, 0] has the interval [0, 0]: d = min(50, 100) = 50
    d = scanline_dissimilarity(np.array([0, 0, 0], np.uint8), np.array([0, 100, 0], np.uint8))
    assert d[1, 1] == 50.0
    # IL(1) = 20 lies inside the right interval [17.5, 32.5] around IR(1) = 25
    d = scanline_dissimilarity(np.array([10, 20, 30], np.uint8), np.array([10, 25, 40], np.uint8))
    assert d[1, 1] == 0.0
    # last pixel: the missing neighbour is the pixel itself, so the right interval at 2 is
    # [32.5, 40] (IL(2) = 30 is 2.5 below) and the left one is [25, 30] (IR(2) = 40 is 10 above)
    assert d[2, 2] == 2.5


@pytest.mark.parametrize("seed", range(5))
def test_bounded_by_absolute_difference(seed):
    left, right = _rows(seed)
    d = scanline_dissimilarity(left, right)
    absdiff = np.abs(left.astype(float)[:, None] - right.astype(float)[None, :])
    assert (d >= 0).all()
    assert (d <= absdiff).all()


@pytest.mark.parametrize("seed", range(5))
def test_symmetric_under_swapping_images(seed):
    left, right = _rows(seed)
    np.testing.assert_array_equal(scanline_dissimilarity(left, right),
                                  scanline_dissimilarity(right, left).T)


@pytest.mark.parametrize("slope, shift", [(2, 0.5), (4, 0.25), (4, 0.5), (2, -0.5)])
def test_linear_ramp_shifted_by_at_most_half_a_pixel_costs_nothing(slope, shift):
    x = np.arange(30)
    left = (20 + slope * x).astype(np.uint8)
    right = (20 + slope * (x + shift)).astype(np.uint8)
    d = scanline_dissimilarity(left, right)
    assert np.diag(d)[1:-1].max() == 0.0  # interior: both neighbours exist
    # one pixel more shift is not free
    assert np.diag(d, k=1)[1:-1].min() > 0.0 or np.diag(d, k=-1)[1:-1].min() > 0.0


def test_constant_rows_cost_their_difference():
    d = scanline_dissimilarity(np.full(10, 70, np.uint8), np.full(10, 110, np.uint8))
    assert (d == 40.0).all()


@pytest.mark.parametrize("seed", range(3))
def test_invariant_to_adding_a_constant_to_both_images(seed):
    rng = np.random.default_rng(seed)
    left = rng.integers(0, 200, 40).astype(np.uint8)
    right = rng.integers(0, 200, 40).astype(np.uint8)
    np.testing.assert_array_equal(scanline_dissimilarity(left, right),
                                  scanline_dissimilarity(left + 37, right + 37))


def test_variation_flags_windows():
    row = np.array([10, 10, 10, 16, 16, 16, 16, 16], np.uint8)[:, None]
    fwd = np.zeros(8, np.bool_)
    bwd = np.zeros(8, np.bool_)
    variation_flags(row, 0, 8, 0, 8, 5, True, fwd, 0)  # window [x, x+2]
    variation_flags(row, 0, 8, 0, 8, 5, False, bwd, 0)  # window [x-2, x]
    assert fwd.tolist() == [False, True, True, False, False, False, False, False]
    assert bwd.tolist() == [False, False, False, True, True, False, False, False]
    # a step of 4 grey levels is not an intensity variation
    small = np.array([10, 10, 10, 14, 14, 14, 14, 14], np.uint8)[:, None]
    flat = np.zeros(8, np.bool_)
    variation_flags(small, 0, 8, 0, 8, 5, True, flat, 0)
    assert not flat.any()
