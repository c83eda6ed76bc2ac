"""Birchfield-Tomasi postprocessing across scanlines (the "column-wise method", ICCV'98).

Works on the dense map of disparity indices from the scanline programme (-1 = no data, which
is never changed, never counted and stops propagation) and on the left image only:

1. coerce: a pixel whose upper and lower neighbours agree takes their value (in place, downward);
2. intensity variation of the left image in 3-pixel windows (max - min >= 5), horizontal (igx)
   and vertical (igy), all three pixels marked;
3. igy runs along a row shorter than 3 pixels are dropped;
4. reliability = length of the vertical run of equal disparity;
5. propagation along columns from pixels with reliability >= ``mr`` (16), up then down, over
   pixels that are not igy and whose reliability is < ``sr`` (12), or whose disparity equals
   the source's ``D`` or is >= ``D + 2``; overwritten pixels get ``D`` and reliability ``mr``;
6. igx runs along a column shorter than 3 are dropped; reliability along rows; the same
   propagation along rows, stopped by igx;
7. mode filters of 11 pixels along y, then along x, with the inertia rule.

Every kernel treats each *row* of its 2-D argument as a line; column passes get transposed
copies. The mode filters read the previous pass's output (not in place).
"""

from __future__ import annotations

import numpy as np

from armstereo.reconstruct.birchfield.common.cost import VARIATION_THRESHOLD
from armstereo.reconstruct.birchfield.common.jit import njit

TH_RELIABLE = 14  # reference code's reliability threshold ...
ALPHA = 0.15  # ... and its tolerance
SLIGHTLY_RELIABLE = round(TH_RELIABLE * (1 - ALPHA))  # 12
MODERATELY_RELIABLE = round(TH_RELIABLE * (1 + ALPHA))  # 16
MIN_GRADIENT_RUN = 3  # shorter runs of intensity variation are "isolated" and dropped
MODE_WINDOW = 11


@njit(cache=True)
def coerce_lines(d):
    """Step 1 along each line: ``d[i] = d[i-1]`` where ``d[i-1] == d[i+1]`` (in place)."""
    for r in range(d.shape[0]):
        line = d[r]
        for i in range(1, line.shape[0] - 1):
            if line[i - 1] == line[i + 1] and line[i - 1] >= 0 and line[i] >= 0:
                line[i] = line[i - 1]


@njit(cache=True)
def variation_marks(img, threshold=VARIATION_THRESHOLD):
    """Step 2 along each line of (n, m, C) uint8 ``img``: every pixel of a 3-pixel window
    varying by >= ``threshold`` in some channel is marked. Returns (n, m) bool."""
    n, m, C = img.shape
    out = np.zeros((n, m), np.bool_)
    for r in range(n):
        for i in range(m - 2):
            for c in range(C):
                a = np.int32(img[r, i, c])
                b = np.int32(img[r, i + 1, c])
                e = np.int32(img[r, i + 2, c])
                if max(a, max(b, e)) - min(a, min(b, e)) >= threshold:
                    out[r, i] = True
                    out[r, i + 1] = True
                    out[r, i + 2] = True
                    break
    return out


@njit(cache=True)
def drop_short_runs(flags, min_run=MIN_GRADIENT_RUN):
    """Steps 3 and 6: clear runs of True shorter than ``min_run`` along each line (in place)."""
    for r in range(flags.shape[0]):
        line = flags[r]
        m = line.shape[0]
        i = 0
        while i < m:
            if not line[i]:
                i += 1
                continue
            j = i
            while j < m and line[j]:
                j += 1
            if j - i < min_run:
                line[i:j] = False
            i = j


@njit(cache=True)
def reliability(d):
    """Step 4: length of the run of equal values each pixel belongs to, along each line."""
    rel = np.zeros(d.shape, np.int32)
    for r in range(d.shape[0]):
        line = d[r]
        m = line.shape[0]
        i = 0
        while i < m:
            j = i
            while j < m and line[j] == line[i]:
                j += 1
            rel[r, i:j] = j - i
            i = j
    return rel


@njit(cache=True, inline="always")
def _can_overwrite(v, rel, grad, D, sr):
    return (not grad) and v >= 0 and (rel < sr or v == D or v >= D + 2)


@njit(cache=True)
def propagate(d, rel, grad, sr=SLIGHTLY_RELIABLE, mr=MODERATELY_RELIABLE):
    """Steps 5/6 along each line (in place on ``d`` and ``rel``): grow every run whose
    reliability is >= ``mr`` up, then down from its end, over overwritable pixels."""
    for r in range(d.shape[0]):
        line = d[r]
        lrel = rel[r]
        lgrad = grad[r]
        m = line.shape[0]
        i = 0
        while i < m:
            if lrel[i] < mr or line[i] < 0:
                i += 1
                continue
            D = line[i]
            j = i - 1
            while j >= 0 and _can_overwrite(line[j], lrel[j], lgrad[j], D, sr):
                line[j] = D
                lrel[j] = mr
                j -= 1
            end = i
            while end + 1 < m and line[end + 1] == D:
                end += 1
            j = end + 1
            while j < m and _can_overwrite(line[j], lrel[j], lgrad[j], D, sr):
                line[j] = D
                lrel[j] = mr
                j += 1
            i = max(j, end + 1)


@njit(cache=True, inline="always")
def _hist_add(hist, n_with, top, v, delta):
    """Add ``delta`` (+-1) to the count of value ``v``; returns the new maximum count."""
    i = v + 1
    n_with[hist[i]] -= 1
    hist[i] += delta
    n_with[hist[i]] += 1
    if hist[i] > top:
        return hist[i]
    if n_with[top] == 0:
        return top - 1
    return top


@njit(cache=True)
def mode_filter(d, n_values, half=MODE_WINDOW // 2):
    """Step 7 along each line; returns a new array. ``n_values``: values lie in [0, n_values).

    A pixel ``v`` takes its window's mode (the most frequent value, ties to the smaller) only
    if the mode's count exceeds the counts of ``v - 1``, ``v`` and ``v + 1`` together;
    otherwise it takes the most frequent of ``v - 1, v, v + 1`` (ties: ``v``, then the
    smaller). The reference code's x pass also accepts a mode within 1 of ``v``: that mode is
    then one of the three, so the rule differs only in ties and one filter serves both passes.
    """
    out = d.copy()
    hist = np.zeros(n_values + 2, np.int32)  # index v + 1, so v - 1 and v + 1 always fit
    n_with = np.zeros(2 * half + 3, np.int32)  # how many values have each count
    for r in range(d.shape[0]):
        line = d[r]
        m = line.shape[0]
        hist[:] = 0
        n_with[:] = 0
        n_with[0] = n_values + 2
        top = 0
        for i in range(min(half, m)):
            if line[i] >= 0:
                top = _hist_add(hist, n_with, top, line[i], 1)
        for i in range(m):
            a = i + half
            if a < m and line[a] >= 0:
                top = _hist_add(hist, n_with, top, line[a], 1)
            b = i - half - 1
            if b >= 0 and line[b] >= 0:
                top = _hist_add(hist, n_with, top, line[b], -1)
            v = line[i]
            if v < 0:
                continue
            if top > hist[v] + hist[v + 1] + hist[v + 2]:
                mode = n_values
                for j in range(max(0, i - half), min(m, i + half + 1)):
                    w = line[j]
                    if w >= 0 and hist[w + 1] == top and w < mode:
                        mode = w
                out[r, i] = mode
            else:
                best = v
                if v >= 1 and hist[v] > hist[v + 1]:
                    best = v - 1
                if hist[v + 2] > hist[best + 1]:
                    best = v + 1
                out[r, i] = best
    return out


def postprocess(disp: np.ndarray, left: np.ndarray, n_values: int) -> np.ndarray:
    """Steps 1-7 of the module doc on (H, W) int32 disparity indices and the (H, W, C) left
    image (docs/birchfield-tomasi.md §6).

    Returns a new (H, W) int32 map; -1 entries are left as they are.
    """
    dT = np.ascontiguousarray(disp.T)
    coerce_lines(dT)
    igx = variation_marks(left)
    igy = np.ascontiguousarray(variation_marks(np.ascontiguousarray(left.transpose(1, 0, 2))).T)
    drop_short_runs(igy)
    propagate(dT, reliability(dT), np.ascontiguousarray(igy.T))
    d = np.ascontiguousarray(dT.T)
    igxT = np.ascontiguousarray(igx.T)
    drop_short_runs(igxT)
    propagate(d, reliability(d), np.ascontiguousarray(igxT.T))
    dT = mode_filter(np.ascontiguousarray(d.T), n_values)
    return mode_filter(np.ascontiguousarray(dT.T), n_values)
