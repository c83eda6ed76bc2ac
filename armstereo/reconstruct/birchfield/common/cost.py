"""Birchfield-Tomasi sampling-insensitive dissimilarity and intensity-variation flags.

Doubled integer units throughout (as in Birchfield's reference code): a pixel's value is stored
as ``2 I``, the half-samples at ``x -+ 1/2`` as the sums ``I(x-1) + I(x)`` and ``I(x) + I(x+1)``.
The dissimilarity of left pixel ``xL`` and right pixel ``xR`` is (PAMI 1998)

    dbar(xL, xR, IL, IR) = max(0, IL(xL) - Imax, Imin - IL(xL))

with ``Imin/Imax`` the min/max of the right image's linear interpolation over
``[xR - 1/2, xR + 1/2]``, and ``d = min(dbar(xL, xR, IL, IR), dbar(xR, xL, IR, IL))``. At a
segment border the missing neighbour is the pixel itself.

Colour rows (``C > 1``) combine the per-channel values by their sum or their maximum.
"""

from __future__ import annotations

import numpy as np

from armstereo.reconstruct.birchfield.common.jit import njit
from armstereo.reconstruct.birchfield.common.minmax import max2, min2

INF = 1 << 29  # cost of an impossible node; sums of two stay below 2**31

VARIATION_THRESHOLD = 5  # grey levels: max - min >= 5 over 3 pixels is an "intensity variation"


@njit(cache=True)
def interval_bounds(row, seg_lo, seg_hi, lo, hi, v2, vmin, vmax, off):
    """Doubled value and doubled min/max of {I(x-1/2), I(x), I(x+1/2)} for pixels ``lo..hi-1``.

    ``row`` is (W, C) uint8; neighbours exist only inside the segment ``[seg_lo, seg_hi)``.
    Pixel ``lo + i`` is written at index ``off + i`` of the (C, n) int32 outputs.
    """
    for c in range(row.shape[1]):
        for x in range(lo, hi):
            i = off + x - lo
            v = 2 * np.int32(row[x, c])
            prev = v
            if x > seg_lo:
                prev = np.int32(row[x - 1, c]) + np.int32(row[x, c])
            nxt = v
            if x < seg_hi - 1:
                nxt = np.int32(row[x, c]) + np.int32(row[x + 1, c])
            v2[c, i] = v
            vmin[c, i] = min(v, min(prev, nxt))
            vmax[c, i] = max(v, max(prev, nxt))


def row_bounds(row: np.ndarray):
    """Doubled ``(value, min, max)`` arrays, each (C, n) int32, of a (n,) or (n, C) uint8 row."""
    row = np.asarray(row, np.uint8)
    row = row[:, None] if row.ndim == 1 else row
    n, C = row.shape
    out = [np.empty((C, n), np.int32) for _ in range(3)]
    interval_bounds(np.ascontiguousarray(row), 0, n, 0, n, *out, 0)
    return tuple(out)


def scanline_dissimilarity(left_row: np.ndarray, right_row: np.ndarray) -> np.ndarray:
    """All-pairs BT dissimilarity of two grey uint8 rows in grey levels: ``out[xL, xR]``."""
    lv, lmin, lmax = (a[0][:, None] for a in row_bounds(left_row))
    rv, rmin, rmax = (a[0][None, :] for a in row_bounds(right_row))
    d_l = np.maximum(0, np.maximum(lv - rmax, rmin - lv))
    d_r = np.maximum(0, np.maximum(rv - lmax, lmin - rv))
    return np.minimum(d_l, d_r) / 2.0


@njit(cache=True)
def dissimilarity_table(lv, lmin, lmax, rv, rmin, rmax, x_lo, combine_max, dis):
    """Fill ``dis[y, k]`` for right pixel ``y`` and left pixel ``x = y + k``.

    Bounds are (C, n) int32 from :func:`interval_bounds`. Nodes with ``x`` outside
    ``[x_lo, nx)`` get :data:`INF`. ``dis`` is (ny, nd) int32. Channels are summed, or with
    ``combine_max`` their maximum is taken.
    """
    C, nx = lv.shape
    ny, nd = dis.shape
    for y in range(ny):
        k_lo = min(nd, max(0, x_lo - y))
        k_hi = max(k_lo, min(nd, nx - y))
        row = dis[y]
        row[:k_lo] = INF
        row[k_hi:] = INF
        out = row[k_lo:k_hi]
        channel_costs(lv[0], lmin[0], lmax[0], rv[0, y], rmin[0, y], rmax[0, y], y + k_lo,
                       out, 0)
        for c in range(1, C):
            channel_costs(lv[c], lmin[c], lmax[c], rv[c, y], rmin[c, y], rmax[c, y],
                           y + k_lo, out, 2 if combine_max else 1)


@njit(cache=True, inline="always")
def channel_costs(lv, lmin, lmax, a, amin, amax, x0, out, how):
    """One channel's dissimilarities of right value ``a`` with left pixels ``x0 ...``:
    ``how`` 0 stores, 1 adds, 2 keeps the maximum (separate loops so each vectorises)."""
    n = out.shape[0]
    lv = lv[x0:x0 + n]
    lmin = lmin[x0:x0 + n]
    lmax = lmax[x0:x0 + n]
    if how == 0:
        for i in range(n):
            b = lv[i]
            out[i] = min(max(0, max(b - amax, amin - b)), max(0, max(a - lmax[i], lmin[i] - a)))
    elif how == 1:
        for i in range(n):
            b = lv[i]
            out[i] += min(max(0, max(b - amax, amin - b)), max(0, max(a - lmax[i], lmin[i] - a)))
    else:
        for i in range(n):
            b = lv[i]
            d = min(max(0, max(b - amax, amin - b)), max(0, max(a - lmax[i], lmin[i] - a)))
            out[i] = max(out[i], d)


@njit(cache=True)
def variation_flags(row, seg_lo, seg_hi, lo, hi, threshold, forward, out, off):
    """``out[off + i]`` = the 3-pixel window at pixel ``lo + i`` varies by >= ``threshold``.

    ``forward``: window [x, x+2] (the left image's test); otherwise [x-2, x] (the right
    image's). Windows are cut at the segment ``[seg_lo, seg_hi)``; a colour row varies if any
    channel does.
    """
    for x in range(lo, hi):
        a = x if forward else max2(seg_lo, x - 2)
        b = min2(seg_hi - 1, x + 2) if forward else x
        flag = False
        for c in range(row.shape[1]):
            mn = 255
            mx = 0
            for j in range(a, b + 1):
                v = np.int32(row[j, c])
                mn = min2(mn, v)
                mx = max2(mx, v)
            if mx - mn >= threshold:
                flag = True
        out[off + x - lo] = flag
