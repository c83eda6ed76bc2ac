"""Options beyond the paper: occlusion marking, left-right check, subpixel refinement.

All work on integer maps of disparity *indices* (``-1`` = none) or on float disparities (NaN =
none) of the left image; ``x_right = x_left - d``.
"""

from __future__ import annotations

import numpy as np

from armstereo.reconstruct.birchfield.jit import njit


@njit(cache=True)
def occluded_by_nearer(disp, margin):
    """Left pixels hidden in the right view by a nearer pixel of the same map.

    Scanning each row from the right, pixel ``x`` is occluded when ``x - d(x)`` lies at least
    ``margin`` pixels right of the leftmost right-image position of the pixels to its right.
    ``margin = 1`` tolerates the one-pixel ties a slanted surface gives in an integer map.
    """
    H, W = disp.shape
    occ = np.zeros((H, W), np.bool_)
    for r in range(H):
        lowest = W + 1 << 20
        for x in range(W - 1, -1, -1):
            d = disp[r, x]
            if d < 0:
                continue
            xr = x - d
            if xr >= lowest + margin:
                occ[r, x] = True
            lowest = min(lowest, xr)
    return occ


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
def median_beyond(padded, low, high, above, below, out):
    """Where the median of a square window of codes may lie outside ``[low, high]``.

    ``padded``: (H + s - 1, W + s - 1) uint8 codes, the window of output pixel ``(y, x)``
    being ``padded[y:y + s, x:x + s]``; ``low``/``high``: (H, W) uint8 bounds per pixel;
    ``above``/``below``: (W,) uint8 work rows (s * s <= 255). Sets ``out[y, x]`` (bool) when
    more than half the window's codes lie above ``high[y, x]`` or below ``low[y, x]``: exactly
    where the window's median does. Counting all s * s codes of every window is cheap as
    byte arithmetic along the row (vectorised), and needs no bounds from smaller blocks.
    """
    H, W = out.shape
    size = padded.shape[0] - H + 1
    half = size * size // 2 + 1
    for y in range(H):
        hi = high[y]
        lo = low[y]
        for x in range(W):
            above[x] = 0
            below[x] = 0
        for dy in range(size):
            row = padded[y + dy]
            for dx in range(size):
                for x in range(W):
                    v = row[x + dx]
                    above[x] += np.uint8(v > hi[x])
                    below[x] += np.uint8(v < lo[x])
        for x in range(W):
            out[y, x] = above[x] >= half or below[x] >= half


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


@njit(cache=True, inner=True)
def _neighbour_bounds(has_a, d_a, has_b, d_b, gap, tolerance, slope, reach):
    """``(lo, hi)``: the disparities a run of flat pixels between the neighbours ``a`` and
    ``b`` (``gap`` pixels apart; ``has_*``: textured with a disparity ``d_*``) may take; lo
    is NaN when none may. One neighbour is enough when the other is a break within ``reach``
    pixels; two must agree within ``tolerance + slope * gap`` (in float64, as the row test
    of :func:`armstereo.reconstruct.stereo._unsupported` states it)."""
    nan = np.float32(np.nan)
    if not has_a:
        d_a = nan
    if not has_b:
        d_b = nan
    if gap <= reach:
        if not has_a:
            d_a = d_b
        if not has_b:
            d_b = d_a
    if not np.float64(abs(d_a - d_b)) <= tolerance + slope * np.float64(gap):  # NaN: reject
        return nan, nan
    tol = np.float32(tolerance)
    return min(d_a, d_b) - tol, max(d_a, d_b) + tol


@njit(cache=True, inner=True)
def _is_anchor(disp, flat, y, x):
    return not flat[y, x] and np.isfinite(disp[y, x])


@njit(cache=True, nogil=True)
def flat_unsupported(disp, flat, tolerance, slope, reach, columns, first, stop, top, bottom,
                     out):
    """Rows ``first .. stop - 1`` of ``out`` (bool): the flat pixels without a disparity and
    those whose disparity the nearest textured pixels of their row (with ``columns``: nor
    of their column) do not confirm.

    ``disp``: (H, W) float32, NaN = none; ``flat``: (H, W) bool. A run of flat pixels with a
    disparity is bounded by the pixels just before and after it (a textured pixel with a
    disparity, an anchor, or else a break); :func:`_neighbour_bounds` gives the disparities
    its pixels may take. ``top``/``bottom``: (W,) int64 work rows. Reads every row of
    ``disp`` (the column test), writes only rows ``first .. stop - 1`` of ``out``.
    """
    H, W = disp.shape
    for y in range(first, stop):
        d = disp[y]
        f = flat[y]
        o = out[y]
        x = 0
        while x < W:
            if not (f[x] and np.isfinite(d[x])):
                o[x] = f[x]
                x += 1
                continue
            s = x
            while x < W and f[x] and np.isfinite(d[x]):
                x += 1
            left, right = s - 1, x  # -1 or W: outside the row
            lo, hi = _neighbour_bounds(left >= 0 and _is_anchor(disp, flat, y, max(left, 0)),
                                       d[max(left, 0)],
                                       right < W and _is_anchor(disp, flat, y, min(right, W - 1)),
                                       d[min(right, W - 1)], right - left, tolerance, slope,
                                       reach)
            for i in range(s, x):
                o[i] = not (d[i] >= lo and d[i] <= hi)
    if not columns:
        return
    # the column test, for the row test's rejects: top[x] is the last pixel above the
    # current row that is no flat pixel with a disparity (-1: none), bottom[x] the first
    # below it, found when first needed (H: none; -1: not yet)
    for x in range(W):
        t = first - 1
        while t >= 0 and flat[t, x] and np.isfinite(disp[t, x]):
            t -= 1
        top[x] = t
        bottom[x] = -1
    for y in range(first, stop):
        d = disp[y]
        f = flat[y]
        o = out[y]
        for x in range(W):
            if not (f[x] and np.isfinite(d[x])):
                top[x] = y
                continue
            if not o[x]:
                continue
            if bottom[x] <= y:
                b = y + 1
                while b < H and flat[b, x] and np.isfinite(disp[b, x]):
                    b += 1
                bottom[x] = b
            t, b = top[x], bottom[x]
            lo, hi = _neighbour_bounds(t >= 0 and _is_anchor(disp, flat, max(t, 0), x),
                                       disp[max(t, 0), x],
                                       b < H and _is_anchor(disp, flat, min(b, H - 1), x),
                                       disp[min(b, H - 1), x], b - t, tolerance, slope, reach)
            o[x] = not (d[x] >= lo and d[x] <= hi)


@njit(cache=True, nogil=True)
def reject_hidden(disp, reject, unsup, use_unsup, hidden, margin, first, stop):
    """Rows ``first .. stop - 1``, in place: NaN in ``disp`` and True in ``reject`` on the
    ``unsup`` pixels (if ``use_unsup``), then (if ``hidden``) on the pixels a nearer pixel
    of the row hides in the right view: ``x - d(x)`` at least ``margin`` pixels right of the
    leftmost ``x' - d(x')`` of the pixels right of it (NaN takes no part). float32 as numpy
    states it: ``float32(x) - d``, ``lowest + float32(margin)``."""
    W = disp.shape[1]
    m = np.float32(margin)
    for y in range(first, stop):
        d = disp[y]
        r = reject[y]
        if use_unsup:
            u = unsup[y]
            for x in range(W):
                if u[x]:
                    r[x] = True
                    d[x] = np.nan
        if not hidden:
            continue
        lowest = np.float32(np.nan)
        for x in range(W - 1, -1, -1):
            xr = np.float32(x) - d[x]
            if xr >= lowest + m:  # False while lowest is NaN, and for NaN
                r[x] = True
                d[x] = np.nan
            if np.isnan(lowest) or xr < lowest:
                lowest = xr
