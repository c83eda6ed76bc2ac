"""The fast paths of the stages after the matching give exactly what their definitions give:
the consensus median computed only where it can change the answer, the flat-pixel test
decided once per run (column pass only at the row's rejects), and the steps on strips of rows
when threads are allowed."""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor

import cv2
import numpy as np
import pytest

from armstereo.reconstruct import consensus, rejection, stereo
from tests.support.images import box_pair

SEED = 14


def consensus_reference(disp, size, dmin, dmax, max_diff):
    """The consensus rule by its definition: the whole-image uint8 median of the codes."""
    out = disp.copy()
    ok = np.isfinite(disp)
    step = max(1, -(-(dmax + 1) // consensus.CONSENSUS_LEVELS))
    code = np.zeros(disp.shape, np.uint8)
    code[ok] = np.rint((disp[ok] - dmin) / step).astype(np.uint8) + 1
    med = cv2.medianBlur(code, size)
    medd = (med.astype(np.float32) - 1) * np.float32(step) + np.float32(dmin)
    with np.errstate(invalid="ignore"):
        outlier = ok & (med > 0) & (np.abs(disp - medd) > max_diff)
    out[outlier] = medd[outlier]
    return out


def surface_with_blobs(rng, shape, dmin, dmax):
    """A piecewise-planar map with sub-pixel values, small blobs off the surface, a few values
    just outside the window (as sub-pixel steps leave them) and NaN holes."""
    H, W = shape
    y, x = np.mgrid[:H, :W].astype(np.float32)
    disp = dmin + dmax * (0.3 + 0.2 * np.sin(x / 17) + 0.1 * (y > H / 2))
    disp += rng.uniform(-0.4, 0.4, shape).astype(np.float32)
    for _ in range(12):  # blobs a few pixels across, far off the surface
        cy, cx = rng.integers(0, H - 4), rng.integers(0, W - 4)
        disp[cy:cy + 3, cx:cx + 4] += np.float32(rng.uniform(-0.3, 0.3) * dmax)
    disp[rng.random(shape) < 0.01] = dmin - 1
    disp[rng.random(shape) < 0.01] = dmin + dmax + 1
    disp = np.clip(disp, dmin - 1, dmin + dmax + 1).astype(np.float32)
    disp[rng.random(shape) < 0.1] = np.nan
    disp[: H // 5, : W // 5] = np.nan  # a hole larger than half a window
    return disp


@pytest.mark.parametrize("size", [7, 9, 11, 13])
@pytest.mark.parametrize("dmax", [31, 300])  # one disparity per code, two per code
def test_consensus_equals_the_whole_image_median(size, dmax):
    rng = np.random.default_rng(SEED + size + dmax)
    for dmin, max_diff in ((0, stereo.SPECKLE_RANGE), (5, 1.0), (2, 0.5)):
        disp = surface_with_blobs(rng, (90, 120), dmin, dmax)
        expected = consensus_reference(disp, size, dmin, dmax, max_diff)
        assert not np.array_equal(expected, disp, equal_nan=True)  # some pixels change
        got = disp.copy()
        consensus.replace_outliers(got, size, dmin, dmax, max_diff)
        assert np.array_equal(got.view(np.uint32), expected.view(np.uint32))


def test_consensus_on_noise_takes_the_whole_image_path_and_agrees():
    """Unstructured maps leave most pixels undecided (the whole-image median runs)."""
    rng = np.random.default_rng(SEED)
    disp = rng.uniform(0, 40, (40, 50)).astype(np.float32)
    disp[rng.random(disp.shape) < 0.3] = np.nan
    expected = consensus_reference(disp, 9, 0, 40, 2.0)
    consensus.replace_outliers(disp, 9, 0, 40, 2.0)
    assert np.array_equal(disp.view(np.uint32), expected.view(np.uint32))


@pytest.mark.parametrize("size", [7, 9, 11, 13])
def test_undecided_kernel_counts_blocks_as_defined(size):
    """The kernel's per-pixel counts against the definition, block by block in numpy: a
    block whose median is beyond a bound counts 9 codes, one with only its extreme beyond 4."""
    rng = np.random.default_rng(SEED + size)
    r = size // 2
    H, W = 23, 31
    hi, mid, lo = (blocky(rng, (H + 2 * r, W + 2 * r), 40, 0).astype(np.uint8) for _ in "abc")
    above = rng.integers(0, 40, (H, W)).astype(np.uint8)
    below = rng.integers(0, 40, (H, W)).astype(np.uint8)
    ok = rng.random((H, W)) < 0.9
    centres = list(range(-(r - 1), r - 1, 3)) + [r - 1]
    n_hi, n_lo = np.zeros((H, W), int), np.zeros((H, W), int)
    for dy in centres:
        for dx in centres:
            at = (slice(r + dy, r + dy + H), slice(r + dx, r + dx + W))
            n_hi += 4 * (hi[at] > above) + 5 * (mid[at] > above)
            n_lo += 4 * (lo[at] < below) + 5 * (mid[at] < below)
    half = size * size // 2 + 1
    expected = ok & ((n_hi >= half) | (n_lo >= half))
    got = np.empty((H, W), np.bool_)
    consensus.undecided_pixels(hi, mid, lo, above, below, ok, np.int64(r),
                               np.array(centres, np.int64), np.int64(half),
                               np.empty((2, W), np.uint8), got)
    assert 0 < expected.sum() < expected.size  # both answers occur
    np.testing.assert_array_equal(got, expected)


def blocky(rng, shape, values, density):
    """Nearest-neighbour enlargement of a small random map: runs and blocks, not noise."""
    H, W = shape
    small = rng.random((max(1, H // 3), max(1, W // 4)))
    big = cv2.resize(small, (W, H), interpolation=cv2.INTER_NEAREST)
    return np.floor(big * values) if values else big < density


@pytest.mark.parametrize("tolerance", [0.0, 0.5, 1.0, 2.0])
def test_flat_test_equals_rows_and_transposed_rows(tolerance):
    """Column support is the row test on the transpose, kept where either confirms."""
    rng = np.random.default_rng(SEED)
    for _ in range(150):
        shape = tuple(int(v) for v in rng.integers(2, 30, 2))
        disp = blocky(rng, shape, 8, 0).astype(np.float32)
        disp += rng.choice(np.float32([0, 0.5, 1, 1.5, 3]), shape) * (rng.random(shape) < 0.3)
        disp[rng.random(shape) < rng.random() * 0.4] = np.nan
        flat = blocky(rng, shape, 0, rng.random()) ^ (rng.random(shape) < 0.05)
        rows = rejection.unsupported(disp, flat, tolerance)
        columns = rejection.unsupported(np.ascontiguousarray(disp.T), np.ascontiguousarray(flat.T),
                                      tolerance).T
        both = rejection.unsupported(disp, flat, tolerance, columns=True)
        np.testing.assert_array_equal(both, rows & columns)
        assert not (rows & ~flat).any()  # only flat pixels are ever rejected


@pytest.mark.parametrize("size", [5, 9])
def test_consensus_on_strips_equals_the_whole_image(size):
    """Strips of rows (threads) read the rows around theirs as they were before any change."""
    rng = np.random.default_rng(SEED + size)
    disp = surface_with_blobs(rng, (120, 90), 2, 31)
    noisy = rng.uniform(0, 33, (30, 90)).astype(np.float32)  # undecided: the strip's median
    disp[60:90] = noisy
    expected = disp.copy()
    consensus.replace_outliers(expected, size, 2, 31, 2.0)
    for strips in ([(0, 1), (1, 50), (50, 120)], [(0, 40), (40, 80), (80, 120)]):
        got = disp.copy()
        with ThreadPoolExecutor(2) as pool:
            consensus.replace_outliers(got, size, 2, 31, 2.0, pool=pool, strips=strips)
        assert np.array_equal(got.view(np.uint32), expected.view(np.uint32))


@pytest.mark.parametrize("options", [{}, {"photo_check": 4.0}, {"subpixel": "none"},
                                     {"postprocess": "none", "occlusions": "fill"},
                                     {"consensus_size": 5, "column_support": False}])
def test_threads_give_the_same_map_bit_for_bit(options):
    """The steps after matching run on strips of rows when threads are allowed: same map."""
    left, right = box_pair(3, 11, (50, 110, 30, 90), shape=(130, 160), seed=9)
    left[95:120, 10:70] = 90  # a flat patch: the texture rule and column support act
    right[95:120, 7:67] = 90
    mask = np.ones(left.shape, bool)
    mask[:, 150:] = False
    mask[40:60, 145:] = True  # ragged: more than one run on some rows
    mask[40:60, 140:145] = False
    one = stereo.birchfield(left, right, 15, min_disparity=1, threads=1, right_mask=mask,
                            **options)
    for threads in (2, 3):
        got = stereo.birchfield(left, right, 15, min_disparity=1, threads=threads,
                                right_mask=mask, **options)
        assert np.array_equal(got.view(np.uint32), one.view(np.uint32))
