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
