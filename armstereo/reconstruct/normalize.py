"""Local normalisation: what the matcher compares when the two views differ in brightness.

Each grey image is replaced by ``128 + scale * (I - mean) / (std + floor)``, the mean and the
standard deviation taken over a ``window`` x ``window`` square of valid pixels around each
pixel (rounded, saturated to uint8). A gain, an offset, a gamma or a vignetting change that
varies slowly across the window leaves the result (almost) unchanged, so the dissimilarity of
two views taken under different light compares their local structure, not their brightness.
``floor`` (grey levels) keeps the noise of a plain surface from being blown up to full
contrast: where the local spread is below it, the result stays near 128.

Sums are whole numbers, so a strip of rows gives exactly the rows of the whole
image (the matcher's threads filter strips side by side: :mod:`.strips`).
"""

from __future__ import annotations

import cv2
import numpy as np


def normalize(grey_image: np.ndarray, mask: np.ndarray, window: int, floor: float,
              scale: float) -> np.ndarray:
    """The locally normalised (H, W) uint8 image of ``grey_image`` (uint8), from the pixels
    ``mask`` marks valid ((H, W) bool; the others read 128). ``window``: odd side in pixels;
    ``floor`` and ``scale`` in grey levels, > 0 (as :class:`.stereo_options.BirchfieldOptions`
    checks). Windows are cut at the image border."""
    m = mask.astype(np.uint8)
    g = grey_image * m  # uint8: masked pixels count as absent, not as black
    k = (window, window)
    # unnormalised integer sums, zero outside the image: exact, so every order of summing
    # (whole image or strip of rows) gives the same numbers
    sums = dict(ddepth=cv2.CV_32S, ksize=k, normalize=False, borderType=cv2.BORDER_CONSTANT)
    count = cv2.boxFilter(m, **sums).astype(np.float32)
    total = cv2.boxFilter(g, **sums).astype(np.float32)
    squares = cv2.sqrBoxFilter(g, cv2.CV_64F, k, normalize=False,
                               borderType=cv2.BORDER_CONSTANT).astype(np.float32)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = total / count
        var = np.maximum(squares / count - mean * mean, 0.0)
        out = (grey_image - mean) * np.float32(scale) / (np.sqrt(var) + np.float32(floor))
    out += np.float32(128)
    out[~mask | (count == 0)] = 128
    return np.clip(np.rint(out), 0, 255).astype(np.uint8)

