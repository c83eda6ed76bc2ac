"""Speckle removal (:mod:`armstereo.reconstruct.speckles`): small islands of disparity go,
and strips of rows side by side give exactly the whole image's map, also for regions that
cross a cut between strips."""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor

import cv2
import numpy as np
import pytest

from armstereo.reconstruct import speckles
from armstereo.reconstruct.speckles import remove_speckles


def whole_image(disp, size, max_diff):
    """The filter by its definition: OpenCV's filterSpeckles on the whole map at once."""
    out = disp.copy()
    codes = np.where(np.isfinite(disp), np.rint(disp * np.float32(16)), -1).astype(np.int16)
    cv2.filterSpeckles(codes, -1, size, int(round(max_diff * 16)))
    out[codes < 0] = np.nan
    return out


def test_small_islands_of_disparity_are_removed():
    disp = np.full((40, 40), 10.0, np.float32)
    disp[10:14, 10:14] = 25.0  # 16 pixels far from their surroundings
    disp[30:, 30:] = 11.5  # a large region within the speckle range of its neighbours
    remove_speckles(disp, 100, 2.0)
    assert np.isnan(disp[10:14, 10:14]).all()
    assert np.isfinite(disp).sum() == 40 * 40 - 16


def islands(rng, shape, levels):
    """A blocky map of a few disparity levels (regions of every size, many crossing any
    row), sub-pixel noise below the speckle range and NaN holes."""
    H, W = shape
    small = rng.integers(0, levels, (H // 3 + 1, W // 3 + 1)).astype(np.float32) * 5
    disp = np.kron(small, np.ones((3, 3), np.float32))[:H, :W]
    disp += rng.uniform(-0.4, 0.4, shape).astype(np.float32)
    disp[rng.random(shape) < 0.05] = np.nan
    return np.ascontiguousarray(disp)


def snake(H, W, first, length):
    """A one-pixel-wide region of ``length`` pixels winding up and down across row
    ``first`` (rows ``first - 3 .. first + 3``, one column to the right at each turn): fewer
    than 8 of its pixels lie in any run of rows on one side of the row."""
    disp = np.full((H, W), np.nan, np.float32)
    disp[:, 1::3] = 50.0  # columns of another disparity between the snake's columns
    y, x, step = first - 3, 0, 1
    for _ in range(length):
        disp[y, x] = 7.0
        if first - 3 <= y + step <= first + 3:
            y += step
        else:  # turn: one pixel right, then back across the row
            x, step = x + 1, -step
    return disp


@pytest.mark.parametrize("threads", [2, 3])
@pytest.mark.parametrize("size", [4, 20, 60])
def test_strips_give_the_whole_image_map(threads, size):
    rng = np.random.default_rng(threads * 100 + size)
    with ThreadPoolExecutor(threads - 1) as pool:
        for levels in (2, 3, 6):
            disp = islands(rng, (int(rng.integers(8 * size, 12 * size)), 70), levels)
            runs = speckles._runs(disp.shape[0], size, threads)
            assert len(runs) == threads  # tall enough: the strips really run
            expected = whole_image(disp, size, 2.0)
            got = disp.copy()
            remove_speckles(got, size, 2.0, pool=pool, threads=threads)
            np.testing.assert_array_equal(np.isnan(got), np.isnan(expected))


@pytest.mark.parametrize("length", [15, 16, 17, 40])
def test_a_region_crossing_the_cut_is_judged_whole(length):
    """The snake has at most 8 pixels a side of the cut: each strip alone would remove it;
    it goes only when the whole of it is small."""
    size, H = 16, 80
    first = speckles._runs(H, size, 2)[1][0]
    disp = snake(H, 60, first, length)
    got = disp.copy()
    with ThreadPoolExecutor(1) as pool:
        remove_speckles(got, size, 2.0, pool=pool, threads=2)
    np.testing.assert_array_equal(np.isnan(got), np.isnan(whole_image(disp, size, 2.0)))
    assert np.isnan(got[disp == 7.0]).all() == (length <= size)


def test_short_images_stay_whole_and_bands_stay_a_minor_share():
    assert speckles._runs(399, 100, 2) == [(0, 399)]  # a band of 200 rows: more than half
    assert speckles._runs(1000, 100, 1) == [(0, 1000)]
    first, second = speckles._runs(1000, 100, 2)
    assert first == (0, 600) and second == (600, 1000)  # 400 rows + a band of 200
    assert len(speckles._runs(1000, 100, 16)) == 3  # 2 bands of 200 rows; a third: 600
