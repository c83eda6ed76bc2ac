"""Synthetic images for matcher tests."""

from __future__ import annotations

import cv2
import numpy as np


def texture(shape, seed, *, blur=1.5, contrast=50.0, channels=1) -> np.ndarray:
    """Band-limited random texture, uint8, grey (H, W) or BGR (H, W, 3): Birchfield-Tomasi
    needs features of 2-3 px at least (per-pixel white noise breaks its sampling-insensitive
    cost, docs/birchfield-tomasi.md §9.1)."""
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(channels):
        noise = cv2.GaussianBlur(rng.standard_normal(shape).astype(np.float32), (0, 0), blur)
        out.append(128.0 + contrast * noise / (3.0 * noise.std()))
    img = np.clip(np.rint(np.dstack(out)), 0, 255).astype(np.uint8)
    return img[:, :, 0] if channels == 1 else img


def box_pair(d_bg, d_fg, box, *, shape=(80, 140), seed=1):
    """A textured background plane at ``d_bg`` and a fronto-parallel box at ``d_fg`` covering
    the left-image rectangle ``box = (x0, x1, y0, y1)``. Returns (left, right)."""
    H, W = shape
    x0, x1, y0, y1 = box
    bg = texture((H, W + d_bg), seed)
    fg = texture((H, W + d_fg), seed + 100)
    xs = np.arange(W)
    left = bg[:, :W].copy()  # background point x seen at x in the left view ...
    left[y0:y1, x0:x1] = fg[y0:y1, x0:x1]
    right = bg[:, d_bg:d_bg + W].copy()  # ... and at x - d_bg in the right view
    covered = (xs + d_fg >= x0) & (xs + d_fg < x1)  # right pixels the box hides
    right[y0:y1, covered] = fg[y0:y1][:, xs[covered] + d_fg]  # box point x seen at x - d_fg
    return left, right
