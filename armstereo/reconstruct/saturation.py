"""Saturated pixels: what a clipped intensity still says, for the Birchfield-Tomasi cost.

A pixel recorded at 255 was at least that bright; one recorded at 0 at most that dark. Where
one view is brighter than the other (a gain, local light), the brighter view clips first, and
the equalisation (:mod:`.equalize`) can only map the clipped level to one value: the
other view's texture there then disagrees with a flat patch at every disparity, and the
programme answers wrongly or not at all (on the Middlebury pairs with the right view x1.25,
3 of tsukuba's 3.3 points of extra bad-2 lay on or next to clipped pixels).

A censored observation gives a bound, not a value. :func:`saturation_codes` marks the pixels
of each view whose grey value is a lower bound (255; an upper bound, 0, on request), with their
neighbours when the matched images carry the edge prefilter (its Sobel reads them);
:func:`open_bounds` opens those pixels' Birchfield-Tomasi intervals on that side, so that they
cost nothing against any value beyond the bound and the programme's smoothness decides there.
Pixels within the camera's range are unchanged.
"""

from __future__ import annotations

import cv2
import numpy as np

TOP, BOTTOM = 1, 2  # code bits: the true value is at least / at most the recorded one
OPEN = np.float32(4096.0)  # beyond any doubled grey level: an interval open on that side


def saturation_codes(grey_l: np.ndarray, grey_r: np.ndarray, *, neighbours: bool,
                     dark: bool = False) -> np.ndarray | None:
    """(2, H, W) uint8 codes of the left and right grey images ((H, W) uint8): TOP where
    the grey level is 255, BOTTOM where it is 0 (``dark``; off by default: on real
    photographs 0 is the black background, seen dark in both views, and opening it let the
    background match dark parts of the object: the dino and temple rings' points outside the
    object's box 10.9 -> 12.1 %), grown by one pixel each way (``neighbours``:
    the matched images are filtered with a 3x3 kernel). None when no pixel of either image is
    saturated (the common case costs one pass over the images). A colour pixel with one
    channel clipped is not coded: pure colours have channels at 0 and 255 on any photograph,
    and censoring them cost accuracy on unchanged pairs (Middlebury bad-2 2.53 -> 2.57 %)."""
    codes = np.empty((2,) + grey_l.shape, np.uint8)
    for side, g in enumerate((grey_l, grey_r)):
        codes[side] = (g == 255) * np.uint8(TOP)
        if dark:
            codes[side] |= (g == 0) * np.uint8(BOTTOM)
    if not codes.any():
        return None
    if neighbours:
        kernel = np.ones((3, 3), np.uint8)
        for side in range(2):  # dilating the bit planes apart keeps them apart
            top = cv2.dilate(codes[side] & TOP, kernel)
            codes[side] = top | cv2.dilate(codes[side] & BOTTOM, kernel)
    return codes


def open_bounds(bounds: np.ndarray, codes_t: tuple[np.ndarray, np.ndarray],
                slack: float) -> None:
    """Open, in place, the intervals ``bounds`` (6, W, nj) float32 of
    :func:`.birchfield.window.lanes.image_bounds` (doubled value, low, high; left then right)
    of the pixels coded in ``codes_t`` ((W, nj) uint8 each, laid out as ``bounds``): TOP
    pixels get no upper end and a lower end ``slack`` (doubled grey levels) under their value
    at most (the edge prefilter adds up to its cap to the recorded level), BOTTOM pixels the
    converse."""
    for side, code in enumerate(codes_t):
        value, lo, hi = bounds[3 * side], bounds[3 * side + 1], bounds[3 * side + 2]
        top, bottom = (code & TOP) > 0, (code & BOTTOM) > 0
        if top.any():
            np.copyto(hi, OPEN, where=top)
            np.minimum(lo, value - np.float32(slack), out=lo, where=top)
        if bottom.any():
            np.copyto(lo, -OPEN, where=bottom)
            np.maximum(hi, value + np.float32(slack), out=hi, where=bottom)
