"""Regenerate ``reference.npz``: the aggregated matcher's output on crops of Middlebury Cones.

Run with the code to be taken as the reference first on the path, e.g. a copy of the tree at
the commit named in README.md: ``PYTHONPATH=/path/to/that/tree python generate.py``. The cases
(crops, masks, options) are stored in the file with the results, so the test needs only it.
"""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np

from armstereo.reconstruct.birchfield.window.aggregate import match_image_aggregated

HERE = Path(__file__).resolve().parent
CONES = HERE.parent / "middlebury" / "cones"

# (name, rows, columns, dmin, nd, occ, rew, rx, ry, slant, masks, textured, threads); 41 rows
# leave a partial last block of 8 or 16; window (7, 9) on 300 columns needs cost divisor q > 1
CASES = [
    ("default", (100, 141), (150, 250), 0, 30, 50, 10, 0, 1, 40, False, True, 1),
    ("paper", (100, 141), (150, 250), 0, 30, 50, 10, 0, 0, -1, False, False, 1),
    ("w35_masks", (100, 141), (150, 250), 2, 28, 50, 10, 1, 2, 40, True, True, 2),
    ("w11_masks", (60, 101), (100, 200), 3, 25, 40, 6, 0, 0, -1, True, True, 1),
    ("noslant_masks", (200, 241), (200, 300), 1, 30, 50, 10, 0, 1, -1, True, False, 2),
    ("tall_window", (150, 191), (100, 200), 0, 30, 50, 10, 2, 5, 40, True, True, 1),
    ("divided", (120, 145), (60, 360), 0, 40, 50, 10, 3, 4, 40, False, True, 2),
]


def crop(case):
    """Grey crops, validity masks and texture flags of one case (seeded)."""
    _, (r0, r1), (c0, c1), *_, masks, textured, _ = case
    left = cv2.imread(str(CONES / "imL.png"), cv2.IMREAD_GRAYSCALE)[r0:r1, c0:c1]
    right = cv2.imread(str(CONES / "imR.png"), cv2.IMREAD_GRAYSCALE)[r0:r1, c0:c1]
    H, W = left.shape
    yy, xx = np.mgrid[:H, :W]
    lmask = np.ones((H, W), bool)
    rmask = np.ones((H, W), bool)
    if masks:  # rectification-like slanted borders, a gap, an empty row
        lmask = (xx > 3 + 0.2 * yy) & (xx < W - 2 - 0.1 * (H - yy))
        rmask = (xx > 8 - 0.15 * yy) & (xx < W - 5 + 0.1 * yy) & (yy % 13 != 4)
        lmask[H // 3] = False
        lmask[H // 2, W // 2:W // 2 + 3] = False
    flags = np.random.default_rng(7).random((H, W)) > 0.2 if textured else None
    return np.ascontiguousarray(left), np.ascontiguousarray(right), lmask, rmask, flags


def run(case):
    name, _, _, dmin, nd, occ, rew, rx, ry, slant, _, _, threads = case
    left, right, lmask, rmask, flags = crop(case)
    return match_image_aggregated(left, right, lmask, rmask, dmin, nd, occ, rew, rx, ry,
                                  slant=slant, textured=flags, threads=threads)


def main() -> None:
    out = {"cases": np.array(json.dumps(CASES))}
    for case in CASES:
        res = run(case)
        out[f"{case[0]}/disp"] = res["disp"]
        out[f"{case[0]}/state"] = res["state"]
    np.savez_compressed(HERE / "reference.npz", **out)


if __name__ == "__main__":
    main()
