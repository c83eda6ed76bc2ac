"""The block-of-rows matcher (birchfield/lanes.py) against the per-row kernel it replaced:
stored outputs of that kernel on crops of Middlebury Cones (tests/data/birchfield_rows), with
validity masks that give every row its own range, texture flags, a partial last block, windows
from 1x1 to 7x11, a cost divisor above 1, one and two threads."""

from __future__ import annotations

import importlib.util
import json

import numpy as np
import pytest
from numba import njit

from armstereo.reconstruct.birchfield.window.aggregate import match_image_aggregated
from armstereo.reconstruct.birchfield.window.simd import LANES, lanewise, vmax, vmin
from tests.support import ROOT

FIXTURE = ROOT / "tests" / "data" / "birchfield_rows"


def _generator():
    spec = importlib.util.spec_from_file_location("birchfield_rows_generate",
                                                  FIXTURE / "generate.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


GENERATE = _generator()
REFERENCE = np.load(FIXTURE / "reference.npz")
CASES = json.loads(str(REFERENCE["cases"]))


@pytest.mark.parametrize("case", CASES, ids=[c[0] for c in CASES])
def test_blocks_of_rows_reproduce_the_per_row_kernel(case):
    name, _, _, dmin, nd, occ, rew, rx, ry, slant, _, _, threads = case
    left, right, lmask, rmask, flags = GENERATE.crop(case)
    out = match_image_aggregated(left, right, lmask, rmask, dmin, nd, occ, rew, rx, ry,
                                 slant=slant, textured=flags, threads=threads)
    np.testing.assert_array_equal(out["disp"], REFERENCE[f"{name}/disp"])
    np.testing.assert_array_equal(out["state"], REFERENCE[f"{name}/state"])


def test_the_cases_cover_what_differs_between_lanes_and_rows():
    """Partial last blocks, masks, a divided cost: the fixture is not a trivial one."""
    heights = {c[1][1] - c[1][0] for c in CASES}
    assert any(h % LANES for h in heights)
    assert any(c[10] for c in CASES) and any(c[12] == 2 for c in CASES)
    for case in CASES:
        disp = REFERENCE[f"{case[0]}/disp"]
        assert (disp >= 0).mean() > 0.5 and len(np.unique(disp)) > 5


@lanewise
def _min_max(b, x, y, lo, hi):
    return {2: vmin(b, x, y), 3: vmax(b, x, y)}


@njit
def _apply_min_max(x, y, lo, hi):
    _min_max(((x, 0), (y, 0), (lo, 0), (hi, 0)), ())


def test_lanewise_min_and_max_are_numbas_per_lane():
    rng = np.random.default_rng(3)
    x = rng.integers(-3, 4, LANES).astype(np.float32)
    y = rng.integers(-3, 4, LANES).astype(np.float32)
    lo, hi = np.zeros(LANES, np.float32), np.zeros(LANES, np.float32)
    _apply_min_max(x, y, lo, hi)
    np.testing.assert_array_equal(lo, np.minimum(x, y))
    np.testing.assert_array_equal(hi, np.maximum(x, y))
