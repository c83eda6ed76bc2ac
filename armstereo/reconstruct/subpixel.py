"""Sub-pixel steps of a matched map: where between the whole disparities a match lies.

``subpixel="fast"`` (the default) is :func:`gradient_step`: one Lucas-Kanade step per pixel
over a small window, each pixel at its own integer disparity, a few percent of the match time.
``"gradient"`` and ``"parabola"`` (:func:`refine`) are the iterated same-surface step and the
windowed SSD parabola of :mod:`.birchfield.refine`, on whole maps after the rejections.
"""

from __future__ import annotations

import cv2
import numpy as np

from armstereo.reconstruct.birchfield.refine import (
    gradient_terms,
    refine_gradient,
    refine_parabola,
)

SUBPIXEL_WINDOW = 5  # "fast" sub-pixel step: window side (pixels)
SUBPIXEL_MIN_GRADIENT = 1e-3  # sum of squared gradients below which no step is taken
# gradient refinement passes: averaged bad-2 3.79 % with 1, 3.72 % with 2, 3.68 % with 3
SUBPIXEL_ITERATIONS = 2
SUBPIXEL_MAX_SHIFT = 1.0  # pixels: no step moves a disparity further


def gradient_step(left: np.ndarray, right: np.ndarray, idx: np.ndarray,
                  dmin: int) -> np.ndarray:
    """Sub-pixel offsets (float32, pixels): one Lucas-Kanade step per pixel over a
    SUBPIXEL_WINDOW square.

    Each pixel contributes at its own integer disparity ``d``: the residual ``e = L(x) -
    R(x - d)`` and the symmetric gradient ``g`` (mean of both images' central differences);
    with ``L(x) ~ R(x - d - delta)`` the window's least-squares step is ``delta = -sum(g e) /
    sum(g^2)``, clamped to +-1 (0 where the window has no gradient). ``left``/``right``: (H,
    W) uint8 grey; ``idx``: int window indices (disparity ``dmin + idx``; -1 = none). The
    per-pixel terms come from one kernel (:func:`gradient_terms`: the gathers at each pixel's
    partner cost numpy a pass each), the window sums from OpenCV.
    """
    # g is a small integer times 1/4 and e an integer: every term, and every window sum
    # below, is exact in float32 whatever the order
    g = np.empty(idx.shape, np.float32)
    minus_e = np.empty(idx.shape, np.float32)  # -g e, so that the window sum is -sum(g e)
    gradient_terms(left, right, np.asarray(idx, np.int32), np.int64(dmin), g, minus_e)
    win = (SUBPIXEL_WINDOW, SUBPIXEL_WINDOW)
    sgg = cv2.boxFilter(g, -1, win, dst=g, normalize=False)
    step = cv2.boxFilter(minus_e, -1, win, dst=minus_e, normalize=False)
    # no gradient, no step: where sgg is 0 (the sums are multiples of 1/16, so none lies
    # between 0 and the threshold) every g, and so the sum of g e, is 0 too: step keeps it
    np.divide(step, sgg, out=step, where=sgg > SUBPIXEL_MIN_GRADIENT)
    return np.clip(step, -SUBPIXEL_MAX_SHIFT, SUBPIXEL_MAX_SHIFT, out=step)


def refine(disp: np.ndarray, left: np.ndarray, right: np.ndarray, mode: str,
           radius: int) -> np.ndarray:
    """The map ``disp`` (float32 disparities, NaN = none) refined from its rounded values
    by ``mode`` ``"gradient"`` (iterated same-surface step) or ``"parabola"`` (SSD at d-1, d,
    d+1) over a ``2 radius + 1`` window of the (H, W) uint8 grey images."""
    whole = np.rint(disp)
    lf, rf = left.astype(np.float32), right.astype(np.float32)
    if mode == "gradient":
        return refine_gradient(lf, rf, whole, radius, SUBPIXEL_ITERATIONS, SUBPIXEL_MAX_SHIFT)
    return refine_parabola(lf, rf, whole, radius)
