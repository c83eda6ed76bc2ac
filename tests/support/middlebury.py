"""The bundled Middlebury pairs (tests/data/middlebury, sources and licence in its README)."""

from __future__ import annotations

import json

import cv2
import numpy as np

from armstereo.io.disparity import read_disparity
from tests.support import MIDDLEBURY


def load_pair(name: str) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict]:
    """(left BGR, right BGR, true disparity (H, W) float32, non-occluded mask (H, W) bool,
    meta.json) of the pair ``name`` (tsukuba, venus, teddy, cones)."""
    folder = MIDDLEBURY / name
    meta = json.loads((folder / "meta.json").read_text())
    left = cv2.imread(str(folder / meta["left"]))
    right = cv2.imread(str(folder / meta["right"]))
    gt = read_disparity(folder / meta["gt"], scale=meta["gt_scale"])
    mask = cv2.imread(str(folder / meta["masks"]["nonocc"]), cv2.IMREAD_GRAYSCALE) > 128
    return left, right, gt, mask, meta


def bench_window(meta: dict) -> int:
    """The benchmark's searched window for a pair: its largest disparity, rounded up to
    the next multiple of 16 minus one (as bench/harness.py searches it)."""
    return -(-(meta["max_disp"] + 1) // 16) * 16 - 1
