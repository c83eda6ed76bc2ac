"""The exact optimum of the scanline programme of :mod:`.dp_pruned` in O(ny nd), vectorised.

Same model (nodes, steps, costs, start and end) as :func:`.dp_pruned.scanline_dp`; no pruning
is needed because every step kind is a running minimum:

- row ``y + 1`` is pulled from row ``y``: ``phi(y+1, k) = d(y+1, k) - reward + min(
  phi(y, k), P(k) + pen_l, R(y + k))``;
- a left occlusion into ``(y+1, k)`` comes from the cheapest ``(y, k')`` with ``k' < k``: the
  exclusive prefix minimum ``P(k)`` along row ``y``;
- a right occlusion into ``(y+1, k)`` (left pixel ``y+k+1``) comes from the cheapest node at
  left pixel ``y + k`` with ``k' > k``: ``R(x)`` is a running minimum per left pixel of
  ``phi + pen_r``, to which row ``y``'s nodes are added only after row ``y + 1`` has read it,
  so it holds exactly the nodes of earlier rows, i.e. ``k' > k``.

Each row takes a short scalar pass (the prefix minimum) and two loops the compiler turns
into SIMD code (dissimilarities; pull and push together). The back-pointers are not stored:
the backtrack re-derives each step from ``phi`` preferring no occlusion, then a left occlusion
(smallest ``k'``), then a right one (largest ``k'``); any such choice is an optimal path.

The forward pass works in float32, not int32: numba widens int32 arithmetic to int64, which
halves the SIMD lanes and lacks native min/max on AVX2 (measured 1.7x slower). Every cost is
an integer (doubled units) and every path cost stays below :data:`EXACT_BELOW`, where float32
holds integers exactly, so the optimum and the backtrack's equality tests are exact; the
caller keeps rows within that bound (:func:`max_exact_width`).
"""

from __future__ import annotations

import numpy as np

from armstereo.reconstruct.birchfield.common.cost import INF, channel_costs
from armstereo.reconstruct.birchfield.common.jit import njit
from armstereo.reconstruct.birchfield.common.states import (
    C0,
    EXACT_BELOW,
    MAX_PIXEL_COST,
    NO_VARIATION_PENALTY,
    VALID_BELOW,
)


def max_exact_width(channels: int, occ: int) -> int:
    """Widest row whose costs stay exact in float32: ``channels`` summed, doubled occlusion
    penalty ``occ``.

    A node costs at most what the constant-disparity path to it costs (C0 plus one
    dissimilarity per right pixel); the candidates compared with it add one penalty at most.
    """
    return (EXACT_BELOW - C0 - 2 * (occ + NO_VARIATION_PENALTY)) // (MAX_PIXEL_COST * channels)


# Inlined: a numba call that passes six 2-D arrays costs ~50 ns, paid here once per node row
# (and per backtrack step for _node_cost); inlining made the scanline programme 2.4x faster
# at 8 disparities, 12 % at 64.
@njit(cache=True, inline="always")
def _costs_of_right_pixel(lv, lmin, lmax, rv, rmin, rmax, y, x_lo, combine_max, out):
    """``out[k]`` = dissimilarity of right pixel ``y`` and left pixel ``y + k`` (INF outside)."""
    C, nx = lv.shape
    nd = out.shape[0]
    k_lo = min(nd, max(0, x_lo - y))
    k_hi = max(k_lo, min(nd, nx - y))
    out[:k_lo] = np.float32(INF)
    out[k_hi:] = np.float32(INF)
    a, b = y + k_lo, y + k_hi
    _grey_costs(lv[0, a:b], lmin[0, a:b], lmax[0, a:b], rv[0, y], rmin[0, y], rmax[0, y],
                out[k_lo:k_hi])
    for c in range(1, C):
        channel_costs(lv[c], lmin[c], lmax[c], rv[c, y], rmin[c, y], rmax[c, y], a,
                      out[k_lo:k_hi], 2 if combine_max else 1)


@njit(cache=True, inline="always")
def _grey_costs(lv, lmin, lmax, v, vmin, vmax, out):
    """One channel's dissimilarities of right value ``v`` with the left pixels (SIMD loop)."""
    zero = np.float32(0.0)
    for i in range(out.shape[0]):
        b = lv[i]
        out[i] = min(max(zero, max(b - vmax, vmin - b)),
                     max(zero, max(v - lmax[i], lmin[i] - v)))


@njit(cache=True, inner=True)
def _penalties(flags, occ, n):
    """Occlusion penalty per pixel: ``occ``, plus the no-variation penalty where not flagged."""
    pen = np.full(n, occ, np.float32)
    for i in range(flags.shape[0]):
        if not flags[i]:
            pen[i] = occ + NO_VARIATION_PENALTY
    return pen


@njit(cache=True, fastmath=True)
def scanline_dp_exact(lv, lmin, lmax, rv, rmin, rmax, x_lo, combine_max, gl, gr, occ, rew,
                      phi, match):
    """Best match sequence of one scanline; returns its cost (``INF`` if there is none).

    ``lv, lmin, lmax`` (C, nx) and ``rv, rmin, rmax`` (C, ny): doubled interval bounds of the
    left/right pixels (:func:`..common.cost.interval_bounds`); left pixels below ``x_lo``
    take no part. ``gl``/``gr``: intensity-variation flags; ``occ``/``rew``: doubled occlusion
    penalty and match reward; ``phi``: (ny, nd) float32 work array (see the module doc).
    Output ``match[x]`` = right pixel matched to left pixel ``x``, or -1.
    """
    ny, nd = phi.shape
    nx = lv.shape[1]
    bl = (lv.astype(np.float32), lmin.astype(np.float32), lmax.astype(np.float32))
    br = (rv.astype(np.float32), rmin.astype(np.float32), rmax.astype(np.float32))
    pen_l = _penalties(gl, occ, nx + nd + 1)
    inf = np.float32(INF)
    rbest = np.full(nx + nd, inf, np.float32)
    dn = np.empty(nd, np.float32)
    a = np.empty(nd, np.float32)
    rw = np.float32(rew)
    _costs_of_right_pixel(bl[0], bl[1], bl[2], br[0], br[1], br[2], 0, x_lo, combine_max, dn)
    for k in range(nd):
        phi[0, k] = min(np.float32(C0) + dn[k], inf)
    for y in range(ny - 1):
        _costs_of_right_pixel(bl[0], bl[1], bl[2], br[0], br[1], br[2], y + 1, x_lo,
                              combine_max, dn)
        p = inf
        for k in range(nd):  # exclusive prefix minimum: the only scalar pass
            a[k] = p + pen_l[y + 1 + k]
            p = min(p, phi[y, k])
        pen_r = np.float32(occ + (0 if gr[y] else NO_VARIATION_PENALTY))
        for k in range(nd):  # pull row y + 1 and push row y into R in one SIMD loop
            s = phi[y, k]
            rb = rbest[y + k]
            phi[y + 1, k] = min(min(min(s, a[k]), rb) + dn[k] - rw, inf)
            rbest[y + k] = min(rb, s + pen_r)
    return _backtrack(lv, lmin, lmax, rv, rmin, rmax, combine_max, phi, pen_l, gr, occ, rew,
                      nx, match)


@njit(cache=True, inline="always")
def _node_cost(lv, lmin, lmax, rv, rmin, rmax, x, y, combine_max):
    """Dissimilarity of left pixel ``x`` and right pixel ``y`` (channels combined)."""
    total = 0
    for c in range(lv.shape[0]):
        b = lv[c, x]
        v = rv[c, y]
        d = min(max(0, max(b - rmax[c, y], rmin[c, y] - b)),
                max(0, max(v - lmax[c, x], lmin[c, x] - v)))
        total = max(total, d) if combine_max else total + d
    return total


@njit(cache=True, inner=True)
def _backtrack(lv, lmin, lmax, rv, rmin, rmax, combine_max, phi, pen_l, gr, occ, rew, nx,
               match):
    """Walk back from the cheapest node at the last left pixel (ties: largest k)."""
    ny, nd = phi.shape
    match[:] = -1
    best = VALID_BELOW
    y = -1
    k = -1
    for k2 in range(nd):
        y2 = nx - 1 - k2
        if 0 <= y2 < ny and phi[y2, k2] <= best and phi[y2, k2] < VALID_BELOW:
            best = phi[y2, k2]
            y = y2
            k = k2
    if k < 0:
        return INF
    while True:
        match[y + k] = y
        if y == 0:
            break
        before = phi[y, k] - _node_cost(lv, lmin, lmax, rv, rmin, rmax, y + k, y,
                                        combine_max) + rew
        if phi[y - 1, k] == before:
            y -= 1
            continue
        kb = -1
        for k2 in range(k):  # left occlusion from row y - 1
            if phi[y - 1, k2] + pen_l[y + k] == before:
                kb = k2
                break
        if kb >= 0:
            y -= 1
            k = kb
            continue
        x = y + k - 1  # right occlusion from left pixel x
        for k2 in range(nd - 1, k, -1):
            y2 = x - k2
            if 0 <= y2 < ny and phi[y2, k2] + occ + (
                    0 if gr[y2] else NO_VARIATION_PENALTY) == before:
                kb = k2
                break
        y = x - kb
        k = kb
    return best
