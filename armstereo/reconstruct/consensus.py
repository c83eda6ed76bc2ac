"""The consensus median: answers that disagree with the surface around them take its median.

The scanline programme decides each row on its own, so a streak a few rows high, or a blob,
can sit at a disparity its surroundings do not share. :func:`replace_outliers` gives every
answered pixel more than ``max_diff`` from the median answer of the square around it that
median (``birchfield(consensus_size=...)``). The median is a uint8 one (OpenCV's), of
disparity codes; for the common square sides it is computed only where bounds from 3x3
blocks say it can change the answer (:func:`_undecided`), which gives the same map for a
fraction of a whole-image median's cost. Strips of rows can run side by side
(:mod:`armstereo.reconstruct.strips`).
"""

from __future__ import annotations

import cv2
import numpy as np

from armstereo.reconstruct.birchfield.common.jit import njit
from armstereo.reconstruct.strips import each_strip

CONSENSUS_LEVELS = 254  # distinct disparity codes of the consensus median (uint8, 0 = NaN)
# consensus squares from this side on: the median only where it can change the answer (below,
# OpenCV's sorting network is cheaper), up to the largest side checked against the whole-image
# median
CONSENSUS_BOUNDED = 7
CONSENSUS_BOUNDED_MAX = 13
CONSENSUS_SHARE = 0.1  # more undecided pixels than this share: the whole-image median
CONSENSUS_MARGIN = 1e-3  # codes: narrows the acceptable codes beyond float32 rounding
CONSENSUS_REACH = 512  # codes: max_diff / step at most this for float32 bounds below 1024


def replace_outliers(disp: np.ndarray, size: int, dmin: int, dmax: int, max_diff: float, *,
                     pool=None, strips: list[tuple[int, int]] | None = None) -> None:
    """Answered pixels more than ``max_diff`` from the median answer of the ``size`` square
    around them take that median (in place): a streak a few rows high, or a blob, that
    disagrees with the surface around it is replaced by what the surface says.

    The median is that of a uint8 copy (OpenCV's any-size median, replicated border): whole
    disparities above ``dmin``, or pairs of them where the window holds more than
    CONSENSUS_LEVELS values; NaN is code 0 and a window whose median is NaN changes nothing.
    From CONSENSUS_BOUNDED on, the median is computed only at the pixels where bounds from
    3x3 blocks (:func:`_undecided`) allow it to change the answer: the same result, without
    the whole-image median of a large square (its cost grows with the side). ``strips`` of
    rows (:mod:`armstereo.reconstruct.strips`) run side by side on ``pool``, with the same
    result.
    """
    H = disp.shape[0]
    if strips is None or len(strips) == 1:
        _consensus_rows(0, H, disp, disp, size, dmin, dmax, max_diff)
        return
    src = disp.copy()  # the strips read the rows around theirs as they were
    each_strip(pool, strips, _consensus_rows, src, disp, size, dmin, dmax, max_diff)


def _consensus_rows(first: int, stop: int, src: np.ndarray, dst: np.ndarray, size: int,
                    dmin: int, dmax: int, max_diff: float) -> None:
    """Rows ``first .. stop - 1`` of :func:`replace_outliers`: medians of ``src``, written
    into ``dst`` (which may be ``src`` when the rows are the whole image)."""
    H = src.shape[0]
    r = size // 2
    a, b = max(0, first - r), min(H, stop + r)  # the rows the squares reach
    part = src[a:b]
    ok_part = np.isfinite(part)
    step = max(1, -(-(dmax + 1) // CONSENSUS_LEVELS))  # disparities per code
    with np.errstate(invalid="ignore"):  # NaN's code is set below
        x = part - np.float32(dmin) if dmin else part  # no pass for nothing (exact either way)
        code = np.rint(x / np.float32(step) if step != 1 else x).astype(np.uint8)
    code += 1
    np.multiply(code, ok_part, out=code)  # NaN: 0
    disp, ok = dst[first:stop], ok_part[first - a:stop - a]
    # the strip's codes with the rows around it, replicated as the image's median does
    # where the strip meets the image's edge
    padded = cv2.copyMakeBorder(code, r - (first - a), r - (b - stop), r, r,
                                cv2.BORDER_REPLICATE)
    at = None
    if (CONSENSUS_BOUNDED <= size <= CONSENSUS_BOUNDED_MAX and disp.flags.c_contiguous
            and max_diff <= CONSENSUS_REACH * step):
        at = np.flatnonzero(_undecided(padded, disp, ok, size, step, dmin, max_diff))
        if at.size > CONSENSUS_SHARE * disp.size:
            at = None  # the whole-image median is cheaper
    if at is None:
        if a == first and b == stop:  # the whole image
            med = cv2.medianBlur(code, size)
        else:
            med = cv2.medianBlur(padded, size)[r:r + stop - first, r:r + disp.shape[1]]
        medd = (med.astype(np.float32) - 1) * np.float32(step) + np.float32(dmin)
        with np.errstate(invalid="ignore"):
            outlier = ok & (med > 0) & (np.abs(disp - medd) > max_diff)
        disp[outlier] = medd[outlier]
        return
    med = _window_median(padded, at, size, disp.shape[1])
    medd = (med.astype(np.float32) - 1) * np.float32(step) + np.float32(dmin)
    flat = disp.ravel()  # a view: disp is C-contiguous
    outlier = (med > 0) & (np.abs(flat.take(at) - medd) > max_diff)
    flat[at[outlier]] = medd[outlier]


def _undecided(padded: np.ndarray, disp: np.ndarray, ok: np.ndarray, size: int, step: int,
               dmin: int, max_diff: float) -> np.ndarray:
    """(H, W) bool: answered pixels whose ``size`` median (of the uint8 codes ``padded``,
    replicated by ``size // 2`` on each side) might lie more than ``max_diff`` from their
    disparity; the median cannot change any other pixel.

    The median exceeds the highest acceptable code ``b`` only if half the window's codes
    do. The window is covered by 3x3 blocks; a block holds at most 9 codes above ``b`` when
    its median is above it, at most 4 when only its maximum is, else none: when these
    counts stay below half the window, the median is at most ``b``. Likewise below the
    lowest acceptable code ``a`` with the blocks' minima (NaN, code 0, counts as below).
    ``a`` and ``b`` are narrowed by CONSENSUS_MARGIN codes, more than float32 rounding
    here and in the test itself, so that a pixel passed over can never change.
    """
    H, W = disp.shape
    r = size // 2
    kernel = np.ones((3, 3), np.uint8)
    hi, lo, mid = cv2.dilate(padded, kernel), cv2.erode(padded, kernel), cv2.medianBlur(padded, 3)
    x = disp  # read only: the codes' scale, exact (disp >= dmin - 1); NaN is masked by ok
    if dmin or step != 1:
        x = disp - np.float32(dmin)
        if step != 1:
            x /= np.float32(step)
    reach = max_diff / step  # codes
    # highest and lowest acceptable codes, floor(x + reach + 1) and ceil(x - reach + 1) as
    # rounding (ties to even) of half a code less and more, clamped to 0..255 (a median at
    # or below 0 changes nothing): uint8 saturation
    above = cv2.add(x, reach + 0.5 - CONSENSUS_MARGIN, dtype=cv2.CV_8U)
    below = cv2.add(x, 1.5 - reach + CONSENSUS_MARGIN, dtype=cv2.CV_8U)
    centres = np.array(list(range(-(r - 1), r - 1, 3)) + [r - 1], np.int64)  # 3x3 blocks
    out = np.empty((H, W), np.bool_)
    # the scratch allocated here: an allocation in a kernel compiles code of its own
    undecided_pixels(hi, mid, lo, above, below, ok, np.int64(r), centres,
                     np.int64(size * size // 2 + 1), np.empty((2, W), np.uint8), out)
    return out


@njit(cache=True, nogil=True)
def undecided_pixels(hi, mid, lo, above, below, ok, r, centres, half, counts, out):
    """The test of :func:`_undecided`: ``out`` (H, W) bool is True where ``ok`` and the 3x3
    blocks of the window (centred ``centres`` rows and columns from the pixel, in the
    codes padded by ``r``) may hold ``half`` codes above ``above`` (a block whose median
    ``mid`` is above counts 9, one with only its maximum ``hi`` above counts 4) or below
    ``below`` (minimum ``lo``). ``counts``: (2, W) uint8 scratch (at most 16 blocks of 9:
    sides up to CONSENSUS_BOUNDED_MAX). One pass that releases the GIL: as 36 OpenCV
    compares and numpy sums per strip, the threads of :func:`replace_outliers` waited on
    each other."""
    # plain 2-D indexing and the centres by index: row slices and iterating over an array
    # compiled more code (first-run compile), for the same speed; the columns unsigned: no
    # wraparound test per load
    H, W = out.shape
    h = np.uint8(half)
    nc = centres.shape[0]
    for y in range(H):
        for x in range(W):  # a plain loop: a slice assignment compiles far more code
            counts[0, x] = 0
            counts[1, x] = 0
        for i in range(nc):
            row = y + r + centres[i]
            for j in range(nc):
                c = r + centres[j]
                for x in range(W):
                    u = np.uint64(c + x)
                    m = mid[row, u]
                    b = above[y, x]
                    a = below[y, x]
                    counts[0, x] += np.uint8((hi[row, u] > b) * 4 + (m > b) * 5)
                    counts[1, x] += np.uint8((lo[row, u] < a) * 4 + (m < a) * 5)
        for x in range(W):
            out[y, x] = ok[y, x] and (counts[0, x] >= h or counts[1, x] >= h)


def _window_median(padded: np.ndarray, at: np.ndarray, size: int, width: int) -> np.ndarray:
    """Medians of the ``size`` squares around the pixels of flat index ``at`` (of an image
    ``width`` wide; ``padded``: its uint8 codes replicated by ``size // 2`` on each side)."""
    y, x = np.divmod(at, width)
    windows = np.lib.stride_tricks.sliding_window_view(padded, (size, size))[y, x]
    middle = size * size // 2
    # int16: numpy's partition has a vectorised path for it, none for uint8
    windows = windows.reshape(len(at), size * size).astype(np.int16)
    return np.partition(windows, middle, axis=1)[:, middle]
