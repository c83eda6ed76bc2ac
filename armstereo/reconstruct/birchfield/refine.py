"""Options beyond the paper: occlusion marking, left-right check, subpixel refinement.

All work on integer maps of disparity *indices* (``-1`` = none) or on float disparities (NaN =
none) of the left image; ``x_right = x_left - d``.
"""

from __future__ import annotations

import numpy as np

from armstereo.reconstruct.birchfield.common.jit import njit
from armstereo.reconstruct.birchfield.common.minmax import max2, min2


@njit(cache=True)
def left_right_mismatch(disp_l, disp_r, dmin, tolerance):
    """Left pixels whose match's right-reference disparity differs by more than ``tolerance``.

    ``disp_l``/``disp_r`` hold window indices (disparity ``dmin + k``), -1 = none; the right
    map is indexed by right-image pixels.
    """
    H, W = disp_l.shape
    bad = np.zeros((H, W), np.bool_)
    for r in range(H):
        for x in range(W):
            k = disp_l[r, x]
            if k < 0:
                continue
            xr = x - dmin - k
            if xr < 0 or disp_r[r, xr] < 0 or abs(disp_r[r, xr] - k) > tolerance:
                bad[r, x] = True
    return bad


@njit(cache=True)
def refine_parabola(left, right, disp, radius):
    """Subpixel offsets by a parabola through windowed SSD costs at ``d - 1, d, d + 1``.

    ``left``/``right``: (H, W) float32 grey images; ``disp``: (H, W) float32 integer-valued
    disparities (NaN = none). The window is (2 radius + 1)^2, restricted to pixels of the same
    surface (integer disparity within 1 of the centre's) and inside both images. Returns the
    refined map; where the centre cost is not a strict minimum the integer value is kept.
    """
    H, W = disp.shape
    out = disp.copy()
    for r in range(H):
        for x in range(W):
            d0 = disp[r, x]
            if np.isnan(d0):
                continue
            d = np.int64(d0)
            c_m = 0.0
            c_0 = 0.0
            c_p = 0.0
            for yy in range(max(0, r - radius), min(H, r + radius + 1)):
                for xx in range(max(0, x - radius), min(W, x + radius + 1)):
                    dd = disp[yy, xx]
                    if not abs(dd - d0) <= 1.0:
                        continue
                    xr = xx - d
                    if xr - 1 < 0 or xr + 1 >= W:
                        continue
                    a = left[yy, xx]
                    e_m = a - right[yy, xr + 1]
                    e_0 = a - right[yy, xr]
                    e_p = a - right[yy, xr - 1]
                    c_m += e_m * e_m
                    c_0 += e_0 * e_0
                    c_p += e_p * e_p
            den = c_m - 2.0 * c_0 + c_p
            if c_0 < c_m and c_0 < c_p and den > 0.0:
                out[r, x] = d0 + 0.5 * (c_m - c_p) / den
    return out


@njit(cache=True, inner=True)
def _sample(row, pos):
    """Linear interpolation of ``row`` at ``pos`` (NaN outside)."""
    if pos < 0.0 or pos > row.shape[0] - 1:
        return np.nan
    i = min(np.int64(pos), row.shape[0] - 2)
    t = pos - i
    return (1.0 - t) * row[i] + t * row[i + 1]


@njit(cache=True, inner=True)
def _gradient_terms(left, right, cur, gg, gd):
    """Per pixel: ``g^2`` and ``g^2 d - g e`` of the 1-D Lucas-Kanade step (0 where unusable)."""
    H, W = cur.shape
    for r in range(H):
        for x in range(W):
            d = cur[r, x]
            gg[r, x] = 0.0
            gd[r, x] = 0.0
            if np.isnan(d) or x == 0 or x == W - 1:
                continue
            pos = x - d
            v0 = _sample(right[r], pos)
            vm = _sample(right[r], pos - 1.0)
            vp = _sample(right[r], pos + 1.0)
            if np.isnan(v0) or np.isnan(vm) or np.isnan(vp):
                continue
            g = 0.25 * (vp - vm + left[r, x + 1] - left[r, x - 1])
            e = left[r, x] - v0
            gg[r, x] = g * g
            gd[r, x] = g * g * d - g * e


@njit(cache=True, inner=True)
def _same_surface_sums(cur, gg, gd, radius, sgg, sgd):
    """Window sums of ``gg``/``gd`` over pixels whose disparity is within 1 of the centre's.

    Separable: a horizontal pass sums each row segment relative to its own centre, the
    vertical pass adds the segments of rows whose centre pixel is within 1 of ours. NaN
    disparities never qualify (their comparison is false).
    """
    H, W = cur.shape
    hgg = np.zeros((H, W), np.float32)
    hgd = np.zeros((H, W), np.float32)
    one = np.float32(1.0)
    for r in range(H):
        row = cur[r]
        g1 = gg[r]
        g2 = gd[r]
        a = hgg[r]
        b = hgd[r]
        for o in range(-radius, radius + 1):
            for x in range(max(0, -o), min(W, W - o)):
                w = np.float32(abs(row[x + o] - row[x]) <= one)
                a[x] += w * g1[x + o]
                b[x] += w * g2[x + o]
    for r in range(H):
        lo = max(0, r - radius)
        hi = min(H, r + radius + 1)
        sgg[r, :] = 0.0
        sgd[r, :] = 0.0
        for yy in range(lo, hi):
            for x in range(W):
                w = np.float32(abs(cur[yy, x] - cur[r, x]) <= one)
                sgg[r, x] += w * hgg[yy, x]
                sgd[r, x] += w * hgd[yy, x]


@njit(cache=True)
def refine_gradient(left, right, disp, radius, iterations, max_shift):
    """Subpixel disparities by iterated 1-D Lucas-Kanade over a window of the same surface.

    Each pixel ``p`` contributes its residual ``e = IL(p) - IR(p - d(p))`` and the symmetric
    gradient ``g`` (mean of IL's and the warped IR's x-derivative); linearising at each pixel's
    own disparity, the window's weighted least-squares disparity is
    ``sum(g^2 d - g e) / sum(g^2)`` over window pixels whose disparity is within 1 of the
    centre's (so windows stop at depth edges; see :func:`_same_surface_sums`). The result stays
    within ``max_shift`` of the input disparity. Returns the refined (H, W) float32 map.
    """
    H, W = disp.shape
    cur = disp.copy()
    gg = np.empty((H, W), np.float32)
    gd = np.empty((H, W), np.float32)
    sgg = np.empty((H, W), np.float32)
    sgd = np.empty((H, W), np.float32)
    for _ in range(iterations):
        _gradient_terms(left, right, cur, gg, gd)
        _same_surface_sums(cur, gg, gd, radius, sgg, sgd)
        for r in range(H):
            for x in range(W):
                if sgg[r, x] > 1e-3:
                    d_in = disp[r, x]
                    cur[r, x] = min(d_in + max_shift, max(d_in - max_shift, sgd[r, x] / sgg[r, x]))
    return cur


@njit(cache=True, nogil=True)
def gradient_terms(left, right, idx, dmin, gg, ge):
    """Per-pixel terms of the fast sub-pixel step: ``gg = g^2`` and ``ge = -g e``.

    ``left``/``right``: (H, W) uint8; ``idx``: (H, W) int32 window indices (disparity ``dmin
    + idx``, -1 = none); ``gg``/``ge``: (H, W) float32, written. ``e = L(x) - R(xr)`` at the
    partner ``xr = x - d``, ``g`` the mean of both images' central differences (left at
    ``x``, 0 in the first and last column; right at ``xr``); both terms are 0 where there is
    no match or ``xr`` is not an inner column. Every value is an integer times 1/16 (``gg``)
    or 1/4 (``ge``), exact in float32.
    """
    H, W = idx.shape
    quarter = np.float32(0.25)
    for y in range(H):
        lrow = left[y]
        rrow = right[y]
        irow = idx[y]
        grow = gg[y]
        erow = ge[y]
        for x in range(W):
            k = irow[x]
            xr = x - dmin - k
            if k < 0 or xr < 1 or xr > W - 2:
                grow[x] = 0
                erow[x] = 0
                continue
            diff = np.int32(rrow[xr + 1]) - np.int32(rrow[xr - 1])
            if 0 < x < W - 1:
                diff += np.int32(lrow[x + 1]) - np.int32(lrow[x - 1])
            g = np.float32(diff) * quarter
            grow[x] = g * g
            erow[x] = np.float32(np.int32(rrow[xr]) - np.int32(lrow[x])) * g


# kinds of pixel for :func:`row_rejects`: 2 * flat + has a disparity
KIND_BREAK, KIND_ANCHOR, KIND_HOLE, KIND_QUERY = 0, 1, 2, 3


@njit(cache=True, nogil=True)
def row_rejects(disp, kind, along, reject, before, tolerance, slope, reach, margin, support,
                test, use_along, apply, hidden, fill, first, stop, out):
    """Rows ``first .. stop - 1``: the flat pixels a row does not confirm, then those a
    nearer pixel hides, or (``fill``) the plain runs :mod:`...plain` fills; one kernel for
    all (and for the tests along the columns, run on transposed copies), as each kernel
    costs its own compile on the first run (~0.1 s before its first line of code).

    ``test``: ``out`` (bool) is set on the flat pixels whose row does not confirm their
    disparity, and on those without one, and with ``use_along`` cleared where ``along``
    (bool) is False. ``disp``: (H, W) float32; ``kind``: (H, W) uint8, ``2 * flat +
    finite(disp)`` (KIND_*). A run of flat pixels with a disparity (queries) is bounded by
    the pixels just before and after it: textured with a disparity (anchors), or else
    breaks, as is the row's edge. With two anchors, their disparities must agree within
    ``tolerance + slope * gap`` (float64; ``gap``: their distance); one anchor is enough
    when the break at the other end is at most ``reach`` pixels from it. A pixel of the run
    is confirmed when its disparity lies within ``tolerance`` (float32) of the anchors'
    range. ``apply``: NaN in ``disp`` and True in ``reject`` where ``out`` is set.

    ``hidden``: then NaN in ``disp`` and True in ``reject`` on the pixels a nearer pixel of
    the row hides in the right view: ``x - d(x)`` at least ``margin`` pixels right of the
    leftmost ``x' - d(x')`` of the pixels right of it (NaN takes no part). float32 as numpy
    states it: ``float32(x) - d``, ``lowest + float32(margin)``.

    ``fill``: only :func:`_fill_row` on each row, with ``before`` (float32) and ``along`` (the
    flat pixels); ``tolerance`` and ``slope`` are then float32 values (as float64), ``support``
    a share. The other modes do not read ``before`` or ``support``.
    """
    W = disp.shape[1]
    nan = np.float32(np.nan)
    tol = np.float32(tolerance)
    m = np.float32(margin)
    for y in range(first, stop):
        d = disp[y]
        if fill:
            _fill_row(d, before[y], along[y], tolerance, slope, support)
            continue
        o = out[y]
        r = reject[y]
        if test:
            k = kind[y]
            a = along[y]
            x = 0
            while x < W:  # one pass: (scalar) loops of their own cost compile time
                if k[x] != KIND_QUERY:
                    o[x] = k[x] == KIND_HOLE  # no disparity: already NaN
                    if o[x] and apply:
                        r[x] = True
                    x += 1
                    continue
                s = x
                while x < W and k[x] == KIND_QUERY:
                    x += 1
                gap = x - s + 1
                d_a = d[s - 1] if s > 0 and k[s - 1] == KIND_ANCHOR else nan
                d_b = d[x] if x < W and k[x] == KIND_ANCHOR else nan
                if gap <= reach:
                    if np.isnan(d_a):
                        d_a = d_b
                    elif np.isnan(d_b):
                        d_b = d_a
                lo = hi = nan  # NaN: no pixel of the run is confirmed
                if np.float64(abs(d_a - d_b)) <= tolerance + slope * np.float64(gap):
                    lo, hi = (d_a, d_b) if d_a <= d_b else (d_b, d_a)
                    lo -= tol
                    hi += tol
                for i in range(s, x):  # the run's neighbours are not queries: never changed
                    o[i] = not (d[i] >= lo and d[i] <= hi) and (a[i] or not use_along)
                    if o[i] and apply:
                        r[i] = True
                        d[i] = nan
        if not hidden:
            continue
        lowest = np.float32(np.inf)  # as numpy's fmin over none: nothing is hidden
        for x in range(W - 1, -1, -1):
            xr = np.float32(x) - d[x]
            if xr >= lowest + m:  # False for NaN
                r[x] = True
                d[x] = nan
            if xr < lowest:  # NaN takes no part
                lowest = xr


@njit(cache=True, inner=True)
def _fill_row(d, b, f, tolerance, slope, support):
    """One row of :func:`.plain.fill_plain` (in place): ``d`` float32 disparities, ``b`` the
    row before the flat test, ``f`` its flat pixels; ``tolerance``/``slope``: float32 values
    as float64 (the anchors' test in float64, the range in float32, as before), ``support``:
    share of the run. Not inlined at numba level: that compiled longer (the callee typed
    again in its caller, bench/results/coldstart.md)."""
    W = d.shape[0]
    tol = np.float32(tolerance)
    x = 0
    while x < W:
        if not f[x]:
            x += 1
            continue
        s = x
        while x < W and f[x]:
            x += 1
        if s == 0 or x == W:  # the run reaches the image's edge: one anchor only
            continue
        d_a = d[s - 1]
        d_b = d[x]
        gap = x - s + 1
        if not abs(d_a - d_b) <= tolerance + slope * gap:  # False for NaN anchors
            continue
        lo = min2(d_a, d_b) - tol
        hi = max2(d_a, d_b) + tol
        agree = 0
        for i in range(s, x):
            if b[i] >= lo and b[i] <= hi:
                agree += 1
        if agree < support * (x - s):
            continue
        step = (d_b - d_a) / np.float32(gap)
        for i in range(s, x):
            if np.isnan(d[i]):
                d[i] = d_a + step * np.float32(i - s + 1)
