"""The numpy set-up of the blocks (birchfield/blocks.py) against the kernels it stands for:
valid runs (matcher.longest_run) and intensity-variation flags (cost.variation_flags) on rows
with random masks, segments cut anywhere, single pixels and empty runs."""

from __future__ import annotations

import numpy as np

from armstereo.reconstruct.birchfield.common.cost import VARIATION_THRESHOLD, variation_flags
from armstereo.reconstruct.birchfield.common.scanline import longest_run
from armstereo.reconstruct.birchfield.window.blocks import longest_runs, variation_map


def _masks(rng, H=40, W=23):
    mask = rng.random((H, W)) < rng.random((H, 1))  # rows from nearly empty to nearly full
    mask[0] = False
    mask[1] = True
    mask[2] = False
    mask[2, 5] = True
    return mask


def test_longest_runs_match_the_kernel():
    rng = np.random.default_rng(3)
    for _ in range(5):
        mask = _masks(rng)
        a, b = longest_runs(mask)
        want = np.array([longest_run.py_func(row) for row in mask])
        np.testing.assert_array_equal(np.stack([a, b], axis=1), want)
    a, b = longest_runs(np.ones((3, 7), bool))
    assert (a == 0).all() and (b == 7).all()


def test_variation_flags_match_the_kernel():
    rng = np.random.default_rng(4)
    img = rng.integers(0, 12, (40, 23), dtype=np.uint8)  # varies by 5 or not, about equally
    lo, hi = longest_runs(_masks(rng))
    for forward in (True, False):
        got = variation_map(img, lo, hi, forward)
        for r in range(img.shape[0]):
            want = np.zeros(img.shape[1], bool)
            variation_flags(img[r][:, None], lo[r], hi[r], lo[r], hi[r], VARIATION_THRESHOLD,
                            forward, want, lo[r])
            np.testing.assert_array_equal(got[r, lo[r]:hi[r]], want[lo[r]:hi[r]])
    lo, hi = np.zeros(40, np.int64), np.full(40, 23, np.int64)  # whole rows: the fast path
    for forward in (True, False):
        got = variation_map(img, lo, hi, forward)
        for r in range(img.shape[0]):
            want = np.zeros(23, bool)
            variation_flags(img[r][:, None], 0, 23, 0, 23, VARIATION_THRESHOLD, forward, want, 0)
            np.testing.assert_array_equal(got[r], want)
