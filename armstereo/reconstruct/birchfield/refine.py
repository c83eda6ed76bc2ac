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
