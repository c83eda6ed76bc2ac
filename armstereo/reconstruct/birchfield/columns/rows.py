"""The per-row kernels of the aggregated programme: one scanline at a time.

The default matcher runs the programme on blocks of rows (:mod:`..window.lanes`, driven by
:func:`..window.aggregate.match_image_aggregated`); these one-row kernels remain for matchers
that prepare each row's costs themselves (:mod:`.vertical` smooths them along the columns
first). The programme and its exactness rule are described in :mod:`..window.aggregate` and
:mod:`..window.lanes`; both compute the same paths from the same costs.

``row_slab`` sums one image row's BT dissimilarities horizontally into a (W, nd) slab,
``row_forward`` runs the programme on a slab of summed costs, ``row_backtrack`` walks back the
cheapest path; ``row_work_arrays`` allocates their work arrays in Python (numba's cold start).
"""

from __future__ import annotations

import numpy as np

from armstereo.reconstruct.birchfield.common.cost import INF
from armstereo.reconstruct.birchfield.common.jit import njit
from armstereo.reconstruct.birchfield.common.states import C0, VALID_BELOW


@njit(cache=True, inline="always")
def _bounds(row, W, v, vmin, vmax):
    """Doubled value and min/max of the half-samples of a filled grey row (BT intervals)."""
    for x in range(W):
        a = 2 * np.float32(row[x])
        p = np.float32(row[max(0, x - 1)]) + np.float32(row[x])
        n = np.float32(row[x]) + np.float32(row[min(W - 1, x + 1)])
        v[x] = a
        vmin[x] = min(a, min(p, n))
        vmax[x] = max(a, max(p, n))


@njit(cache=True, inline="always")
def _bt_costs(lv, lmin, lmax, a, amin, amax, out):
    """BT dissimilarity of one right pixel (``a`` in ``[amin, amax]``) with the left pixels
    ``lv`` (in ``[lmin, lmax]``); slices indexed from 0 so the loop vectorises."""
    zero = np.float32(0.0)
    for i in range(out.shape[0]):
        b = lv[i]
        out[i] = min(max(zero, max(b - amax, amin - b)), max(zero, max(a - lmax[i], lmin[i] - a)))


@njit(cache=True, fastmath=True, inner=True)
def row_slab(left, right, r, dmin, rx, lb, rbnd, raw, out):
    """``out[xr, k]``: sum over ``|dx| <= rx`` of the BT cost of right pixel ``xr + dx`` and left
    pixel ``xr + dx + dmin + k`` (columns clamped to the image) of image row ``r``."""
    W, nd = out.shape
    lv, lmin, lmax = lb
    rv, rmin, rmax = rbnd
    _bounds(left[r], W, lv, lmin, lmax)
    _bounds(right[r], W, rv, rmin, rmax)
    zero = np.float32(0.0)
    dst = out if rx == 0 else raw  # no horizontal sum: costs go straight to the output
    for xr in range(W):
        a = rv[xr]
        amin = rmin[xr]
        amax = rmax[xr]
        row = dst[xr]
        x0 = xr + dmin
        n_in = max(0, min(nd, W - x0))  # left pixels inside the image: one SIMD loop
        _bt_costs(lv[x0:x0 + n_in], lmin[x0:x0 + n_in], lmax[x0:x0 + n_in], a, amin, amax,
                  row[:n_in])
        if n_in < nd:  # past the right edge the edge pixel stands in
            b = lv[W - 1]
            edge = min(max(zero, max(b - amax, amin - b)),
                       max(zero, max(a - lmax[W - 1], lmin[W - 1] - a)))
            for k in range(n_in, nd):
                row[k] = edge
    if rx == 0:
        return
    # running horizontal sum, vectorised over k (plain loops: numba's array expressions and
    # slice copies compile a costly shape-error path)
    acc = out[0]
    for k in range(nd):
        acc[k] = 0.0
    for dx in range(-rx, rx + 1):
        src = raw[min(W - 1, max(0, dx))]
        for k in range(nd):
            acc[k] += src[k]
    for xr in range(1, W):
        add = raw[min(W - 1, xr + rx)]
        sub = raw[max(0, xr - rx - 1)]
        prev = out[xr - 1]
        dst = out[xr]
        for k in range(nd):
            dst[k] = prev[k] + (add[k] - sub[k])


@njit(cache=True, fastmath=True, inner=True)
def row_forward(cost, x_lo, nx, pen_l, gr, occ, novar, rew, slant, q, phi, rbest, a, dn):
    """The exact programme of :mod:`..paper.dp_exact` on a (ny, nd) slab of summed costs, plus
    one-pixel jumps (a slanted surface rather than an occlusion) at the penalty ``slant``,
    allowed with or without intensity variation: into ``(y + 1, k)`` from ``(y, k - 1)`` (one
    left pixel skipped) and from ``(y - 1, k + 1)`` (one right pixel skipped).

    ``phi`` is padded: node ``(y, k)`` is ``phi[y + 1, k + 1]``; row 0 and columns 0 and
    ``nd + 1`` stay INF so that the shifted reads need no tests. ``rbest`` (>= ny + nd),
    ``a`` and ``dn`` (nd) are float32 work arrays.
    """
    ny = cost.shape[0]
    nd = cost.shape[1]
    inf = np.float32(INF)
    for k in range(nd + 2):
        phi[0, k] = inf
    for y in range(1, ny + 1):
        phi[y, 0] = inf
        phi[y, nd + 1] = inf
    for i in range(ny + nd):
        rbest[i] = inf
    iq = np.float32(1.0 / q)
    _load(cost, 0, x_lo, nx, q, iq, dn)
    for k in range(nd):
        phi[1, k + 1] = min(np.float32(C0) + dn[k], inf)
    for y in range(ny - 1):
        _load(cost, y + 1, x_lo, nx, q, iq, dn)
        prev = phi[y]
        cur = phi[y + 1]
        nxt = phi[y + 2]
        p = inf
        for k in range(nd):
            a[k] = p + pen_l[y + 1 + k]
            p = min(p, cur[k + 1])
        pen_r = np.float32(occ + (0 if gr[y] else novar))
        rb_row = rbest[y:y + nd]
        rw = rew[y + 1:y + 1 + nd]
        for k in range(nd):
            s = cur[k + 1]
            rb = rb_row[k]
            jump = min(cur[k], prev[k + 2]) + slant
            nxt[k + 1] = min(min(min(s, a[k]), min(rb, jump)) + dn[k] - rw[k], inf)
            rb_row[k] = min(rb, s + pen_r)


@njit(cache=True, inline="always")
def _load(cost, y, x_lo, nx, q, iq, out):
    """Row ``y`` of the slab as node costs (INF where the left pixel ``y + k`` is outside
    ``[x_lo, nx)``), divided by ``q``."""
    nd = out.shape[0]
    k_lo = min(nd, max(0, x_lo - y))
    k_hi = max(k_lo, min(nd, nx - y))
    inf = np.float32(INF)
    src = cost[y]
    if q == 1:
        for k in range(nd):
            out[k] = src[k] if k_lo <= k < k_hi else inf
    else:
        for k in range(nd):
            out[k] = np.floor(src[k] * iq) if k_lo <= k < k_hi else inf


@njit(cache=True, inline="always")
def _node(cost, y, k, q, iq):
    c = cost[y, k]
    return c if q == 1 else np.floor(c * iq)


@njit(cache=True, inner=True)
def row_backtrack(cost, x_lo, nx, phi, pen_l, gr, occ, novar, rew, slant, q, match):
    """Walk back from the cheapest node at the last left pixel (ties: largest k); as in
    the backtrack of :mod:`..paper.dp_exact`, each step re-derived from the padded ``phi``
    of :func:`row_forward` (preference: no jump, one-pixel jumps, occlusions)."""
    ny, nd = cost.shape
    iq = np.float32(1.0 / q)
    for x in range(match.shape[0]):
        match[x] = -1
    best = np.float32(VALID_BELOW)
    y = -1
    k = -1
    for k2 in range(nd):
        y2 = nx - 1 - k2
        if 0 <= y2 < ny and phi[y2 + 1, k2 + 1] <= best and phi[y2 + 1, k2 + 1] < VALID_BELOW:
            best = phi[y2 + 1, k2 + 1]
            y = y2
            k = k2
    if k < 0:
        return False
    while True:
        match[y + k] = y
        if y == 0:
            break
        before = phi[y + 1, k + 1] - _node(cost, y, k, q, iq) + rew[y + k]
        if phi[y, k + 1] == before:
            y -= 1
            continue
        if phi[y, k] + slant == before:
            y -= 1
            k -= 1
            continue
        if phi[y - 1, k + 2] + slant == before:
            y -= 2
            k += 1
            continue
        kb = -1
        for k2 in range(k):
            if phi[y, k2 + 1] + pen_l[y + k] == before:
                kb = k2
                break
        if kb >= 0:
            y -= 1
            k = kb
            continue
        x = y + k - 1
        for k2 in range(nd - 1, k, -1):
            y2 = x - k2
            if 0 <= y2 < ny and phi[y2 + 1, k2 + 1] + np.float32(
                    occ + (0 if gr[y2] else novar)) == before:
                kb = k2
                break
        if kb < 0:  # cannot happen with exact costs; end the walk rather than loop
            return False
        y = x - kb
        k = kb
    return True


def row_work_arrays(W: int, nd: int, ry: int) -> tuple:
    """Work arrays of a one-row matcher (as :mod:`.vertical` uses them), allocated here rather
    than in the kernel: every array type a kernel creates compiles its own allocation code
    (numba's cold start).

    ``(ring, raw, total, phi, vec, flags, ints, sloc)``: the ``2 ry + 1`` row slabs, the
    unsummed slab and their running sum (zeroed), each (W, nd) float32; the padded programme
    (W + 1, nd + 2) float32; 11 float32 vectors (BT bounds of both rows, penalties, rewards,
    running minima, scratch), (2, W) bool variation flags, (2, W) int32 matches and
    decoded disparities, (W,) uint8 states.
    """
    f32 = np.float32
    return (np.empty((2 * ry + 1, W, nd), f32), np.empty((W, nd), f32), np.zeros((W, nd), f32),
            np.empty((W + 1, nd + 2), f32), np.empty((11, W + nd + 1), f32),
            np.empty((2, W), np.bool_), np.empty((2, W), np.int32), np.empty(W, np.uint8))
