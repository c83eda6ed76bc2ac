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
    k = (window, window)
    # unnormalised integer sums, zero outside the image: exact (below 2 ** 24, so in float32
    # too: OpenCV sums 8-bit images in integers and converts the sums), so every order of
    # summing (whole image or strip of rows) gives the same numbers
    sums = dict(ksize=k, normalize=False, borderType=cv2.BORDER_CONSTANT)
    whole = bool(mask.all())
    if whole:  # no fill to leave out: the counts are those of the window within the image
        g = grey_image
        count = np.outer(_inside(grey_image.shape[0], window),
                         _inside(grey_image.shape[1], window))
    else:
        m = mask.astype(np.uint8)
        g = grey_image * m  # uint8: masked pixels count as absent, not as black
        count = cv2.boxFilter(m, cv2.CV_32F, **sums)
    total = cv2.boxFilter(g, cv2.CV_32F, **sums)
    # OpenCV sums an 8-bit image's squares in int32: beyond that, in float64 (then rounded)
    wide = window * window * 255 * 255 >= 2 ** 31
    squares = cv2.sqrBoxFilter(g, cv2.CV_64F if wide else cv2.CV_32F, **sums)
    squares = squares.astype(np.float32) if wide else squares
    # the float32 steps of (I - mean) * scale / (std + floor) + 128, in place
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = np.divide(total, count, out=total)
        var = np.divide(squares, count, out=squares)
        var -= mean * mean
        np.maximum(var, np.float32(0.0), out=var)
        std = np.sqrt(var, out=var)
        std += np.float32(floor)
        out = np.subtract(grey_image, mean, out=mean)
        out *= np.float32(scale)
        out /= std
    out += np.float32(128)
    if not whole:  # every window of a whole image holds its own pixel: count > 0
        out[~mask | (count == 0)] = 128
    np.rint(out, out=out)
    return np.clip(out, 0, 255, out=out).astype(np.uint8)


def _inside(n: int, window: int) -> np.ndarray:
    """(n,) float32: how many of the ``window`` rows (or columns) centred on each of ``n``
    lie within the image."""
    i = np.arange(n)
    r = window // 2
    return (np.minimum(i + r, n - 1) - np.maximum(i - r, 0) + 1).astype(np.float32)
