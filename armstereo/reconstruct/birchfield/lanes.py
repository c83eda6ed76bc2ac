"""The programme of :mod:`.aggregate` on a block of :data:`LANES` image rows at once.

Each row's programme is a loop over its right pixels with, per right pixel, a loop over the
disparity indices ``k`` (a running minimum over ``k`` among them: a serial dependence). Run
one row at a time, only the inner loop over ``k`` can use SIMD, and the running minimum not at
all. Here the rows of a block are the innermost, contiguous axis of every array (``phi[x, k,
lane]``), so every step of the programme, running minimum included, is one vector operation
across rows.

Rows differ in geometry (validity masks give each its own right pixels ``[r0, r1)`` and
shifted left pixels ``[x0, u1)``), so the programme is written in image coordinates: node
``(x, k)`` pairs right pixel ``x`` with shifted left pixel ``u = x + k``; its cost is INF
where ``u`` lies outside the lane's ``[x0, u1)``. All lanes step through the right pixels of
the block's union of ranges; a lane's values before its own ``r0`` are garbage and are reset
when it starts (the row before it to INF, its first row to the start costs, its running
minima to INF), and its values from ``r1`` on are never read. Every lane therefore does the
same float32 operations in the same order as the one-row programme of :mod:`.aggregate`:
identical costs, identical paths. The backtrack stays per lane (scalar).

The kernels are small and called from Python per block (:func:`.aggregate.match_image_aggregated`):
numba then compiles each once, instead of re-optimising every callee inside one large kernel
(the first run's compile time, bench/results/coldstart.md).
"""

from __future__ import annotations

import numpy as np

from armstereo.reconstruct.birchfield.cost import INF, VARIATION_THRESHOLD, variation_flags
from armstereo.reconstruct.birchfield.dp_exact import VALID_BELOW
from armstereo.reconstruct.birchfield.dp_pruned import C0
from armstereo.reconstruct.birchfield.jit import njit
from armstereo.reconstruct.birchfield.matcher import _begin_row, _store_row
from armstereo.reconstruct.birchfield.simd import LANES, lanewise, vmin

# rows of the (GEO, LANES) int64 geometry of a block: the valid runs of the left
# (la, lb) and right (ra, rb) rows, the programme's ranges (r0, r1, x0, u1), active flag
GEO = 9
LA, LB, R0, R1, X0, U1, RA, RB, ACTIVE = range(GEO)
OCC, REW, NOVAR, SLANT = range(4)  # the scaled penalties in ``pens``


@njit(cache=True, nogil=True)
def lane_setup(left3, right3, lmask, rmask, textured, row0, dmin, nd, pens, disp, state, geo,
               pen_l, rew, pen_r, flags):
    """Reset the output rows ``row0 .. row0 + LANES - 1`` and fill, per lane, the geometry
    ``geo`` and the penalties in image coordinates: ``pen_l[u]`` (left occlusion ending before
    shifted left pixel ``u``), ``rew[u]`` (reward for matching ``u``), ``pen_r[x]`` (right
    occlusion after right pixel ``x``). Returns the block's range ``(x_begin, x_end)`` of right
    pixels (empty if no lane is active)."""
    H = lmask.shape[0]
    zero_f = np.float32(0.0)
    for u in range(pen_l.shape[0]):  # finite values where no lane is defined (garbage lanes)
        for lane in range(LANES):
            pen_l[u, lane] = zero_f
            rew[u, lane] = zero_f
    for x in range(pen_r.shape[0]):
        for lane in range(LANES):
            pen_r[x, lane] = zero_f
    x_begin, x_end = lmask.shape[1], 0
    for lane in range(LANES):
        geo[ACTIVE, lane] = 0
        r = row0 + lane
        if r >= H:
            continue
        la, lb, r0, r1, x0, u1, ra, rb = _begin_row(lmask[r], rmask[r], dmin, nd, disp[r],
                                                    state[r])
        if r1 <= r0 or u1 <= x0:
            continue
        g = geo[:, lane]
        g[LA], g[LB], g[R0], g[R1], g[X0], g[U1], g[RA], g[RB] = la, lb, r0, r1, x0, u1, ra, rb
        g[ACTIVE] = 1
        x_begin, x_end = min(x_begin, r0), max(x_end, r1)
        _lane_penalties(left3[r], right3[r], textured[r], g, dmin, nd, pens, lane, pen_l, rew,
                        pen_r, flags[0], flags[1])
    return x_begin, x_end


@njit(cache=True, inline="always")
def _lane_penalties(left3, right3, textured, g, dmin, nd, pens, lane, pen_l, rew, pen_r, gl,
                    gr):
    """One lane's penalties and rewards as :func:`.aggregate.match_block` sets them for a row
    (local left pixel ``i`` is shifted left pixel ``r0 + i``)."""
    r0, r1, x0, u1 = g[R0], g[R1], g[X0], g[U1]
    nx, x_lo = u1 - r0, x0 - r0
    occ_s, rew_s, novar = pens[OCC], pens[REW], pens[NOVAR]
    # np.int64/np.bool_: plain constants would be typed as literals, and each literal value
    # compiles its own copy of the called kernel
    threshold, zero = np.int64(VARIATION_THRESHOLD), np.int64(0)
    for x in range(gl.shape[0]):
        gl[x] = False
    variation_flags(left3, g[LA], g[LB], x0 + dmin, u1 + dmin, threshold, np.bool_(True), gl,
                    x_lo)
    variation_flags(right3, g[RA], g[RB], r0, r1, threshold, np.bool_(False), gr, zero)
    for i in range(nx + nd + 1):
        pen_l[r0 + i, lane] = occ_s if i < nx and gl[i] else occ_s + novar
        rew[r0 + i, lane] = rew_s if i < nx and textured[r0 + dmin + i] else np.float32(0.0)
    for y in range(r1 - r0):
        pen_r[r0 + y, lane] = np.float32(occ_s + (0 if gr[y] else novar))


@njit(cache=True, nogil=True, fastmath=True)
def lane_costs(left, right, row0, rx, ry, dmin, q, geo, x_begin, x_end, bounds, col, raw, dn):
    """Node costs of the block: ``dn[x, k, lane]`` for right pixels ``x_begin .. x_end - 1``,
    the BT dissimilarities of :func:`.aggregate._row_slab` summed over the ``(2 ry + 1) x
    (2 rx + 1)`` window (image rows and columns clamped), divided by ``q`` (floor), INF where
    ``x + k`` is outside the lane's ``[x0, u1)`` (as :func:`.aggregate._load`).

    ``left``/``right``: (H, W) uint8 filled grey images. Work arrays: ``bounds`` (6, W,
    LANES + 2 ry), ``col`` (LANES + 2 ry), ``raw`` (W, nd, LANES) (unused if ``rx`` is 0).
    Every sum is of integers below float32's exact range, so its order does not change it.
    """
    W = left.shape[1]
    _lane_bounds(left, right, row0 - ry, bounds)
    xa, xb = max(0, x_begin - rx), min(W, x_end + rx)
    if rx == 0:
        for x in range(xa, xb):
            _vertical_sums(bounds, x, dmin, ry, col, dn[x])
            _finish(dn[x], x, geo, q)
        return
    for x in range(xa, xb):
        _vertical_sums(bounds, x, dmin, ry, col, raw[x])
    for x in range(x_begin, x_end):
        out = dn[x]
        _copy(raw[max(0, x - rx)], out)
        for dx in range(-rx + 1, rx + 1):
            _add(raw[min(W - 1, max(0, x + dx))], out)
        _finish(out, x, geo, q)


@njit(cache=True, inline="always")
def _lane_bounds(left, right, top, bounds):
    """Doubled value and min/max of the half-samples (BT intervals, as
    :func:`.aggregate._bounds`) of image rows ``top ..`` (clamped), row ``j`` of the block in
    column ``j``: ``bounds[0..2]`` left, ``bounds[3..5]`` right."""
    H, W = left.shape
    for j in range(bounds.shape[2]):
        r = min(H - 1, max(0, top + j))
        _row_bounds(left[r], j, bounds[0], bounds[1], bounds[2])
        _row_bounds(right[r], j, bounds[3], bounds[4], bounds[5])


@njit(cache=True, inline="always")
def _row_bounds(row, j, v, vmin, vmax):
    W = row.shape[0]
    for x in range(W):
        a = 2 * np.float32(row[x])
        p = np.float32(row[max(0, x - 1)]) + np.float32(row[x])
        n = np.float32(row[x]) + np.float32(row[min(W - 1, x + 1)])
        v[x, j] = a
        vmin[x, j] = min(a, min(p, n))
        vmax[x, j] = max(a, max(p, n))


@njit(cache=True, inline="always")
def _vertical_sums(bounds, x, dmin, ry, col, out):
    """``out[k, lane]``: BT dissimilarity of right pixel ``x`` and left pixel ``x + dmin + k``
    (the last column past the right edge) summed over the ``2 ry + 1`` rows around the lane;
    ``col`` (>= LANES + 2 ry) is scratch."""
    W = bounds.shape[1]
    nj = bounds.shape[2]
    zero = np.float32(0.0)
    rv, rmin, rmax = bounds[3, x], bounds[4, x], bounds[5, x]
    for k in range(out.shape[0]):
        u = min(W - 1, x + dmin + k)
        lv, lmin, lmax = bounds[0, u], bounds[1, u], bounds[2, u]
        for j in range(nj):
            b = lv[j]
            a = rv[j]
            col[j] = min(max(zero, max(b - rmax[j], rmin[j] - b)),
                         max(zero, max(a - lmax[j], lmin[j] - a)))
        o = out[k]
        for lane in range(LANES):
            o[lane] = col[lane]
        for t in range(1, 2 * ry + 1):
            for lane in range(LANES):
                o[lane] += col[lane + t]


@njit(cache=True, inline="always")
def _copy(src, dst):
    for k in range(dst.shape[0]):
        for lane in range(LANES):
            dst[k, lane] = src[k, lane]


@njit(cache=True, inline="always")
def _add(src, dst):
    for k in range(dst.shape[0]):
        for lane in range(LANES):
            dst[k, lane] += src[k, lane]


@njit(cache=True, inline="always")
def _finish(out, x, geo, q):
    """Node costs of right pixel ``x`` in place: divided by ``q``, INF outside ``[x0, u1)``."""
    inf = np.float32(INF)
    iq = np.float32(1.0 / q)
    x0, u1 = geo[X0], geo[U1]
    for k in range(out.shape[0]):
        o = out[k]
        u = x + k
        for lane in range(LANES):
            ok = x0[lane] <= u < u1[lane]
            c = o[lane] if q == 1 else np.floor(o[lane] * iq)
            o[lane] = c if ok else inf


@njit(cache=True, nogil=True, fastmath=True)
def lane_forward(dn, geo, x_begin, x_end, pen_l, rew, pen_r, slant, phi, rbest, run):
    """The forward pass of :func:`.aggregate._forward` for every lane in lockstep.

    Node ``(x, k)`` of a lane is ``phi[x + 1, k + 1, lane]`` (row 0 and columns 0 and
    ``nd + 1`` stay INF); ``rbest[u, lane]``: the running minimum of right-occlusion costs
    into shifted left pixel ``u``; ``run`` (LANES,) float32 scratch. ``slant``: the scaled
    one-pixel-jump penalty (INF: none).
    """
    nd = dn.shape[1]
    inf = np.float32(INF)
    for u in range(x_begin, x_end + nd):
        for lane in range(LANES):
            rbest[u, lane] = inf
    for x in range(x_begin, x_end):
        for lane in range(LANES):
            if geo[ACTIVE, lane] and geo[R0, lane] == x:
                _start_lane(dn[x], lane, phi[x], phi[x + 1], rbest[x:x + nd])
        if x + 1 < x_end:
            _step(dn[x + 1], phi[x], phi[x + 1], phi[x + 2], pen_l[x + 1:x + 1 + nd],
                  rew[x + 1:x + 1 + nd], pen_r[x], rbest[x:x + nd], slant, run)


@njit(cache=True, inline="always")
def _start_lane(d, lane, before, first, rbest):
    """A lane's first right pixel: nothing before it, its nodes start at ``C0`` plus their
    cost, no right occlusion yet (the one-row programme's initial state)."""
    inf = np.float32(INF)
    for c in range(before.shape[0]):
        before[c, lane] = inf
    for k in range(d.shape[0]):
        first[k + 1, lane] = min(np.float32(C0) + d[k, lane], inf)
        rbest[k, lane] = inf


@njit(cache=True, inline="always")
def _step(d, prev, cur, nxt, pen_l, rew, pen_r, rbest, slant, run):
    """Nodes of the next right pixel from the current (``cur``) and previous (``prev``) ones;
    the same operations, in the same order, as one step of :func:`.aggregate._forward`,
    whose running minimum over ``k`` (left occlusions) is ``run`` here, one per lane."""
    inf = np.float32(INF)
    for lane in range(LANES):
        run[lane] = inf
    for k in range(d.shape[0]):
        _node_update((cur[k], cur[k + 1], prev[k + 2], d[k], pen_l[k], rew[k], rbest[k], pen_r,
                      run, nxt[k + 1]), (slant, inf))


@lanewise
def _node_update(b, c0, c1, p2, dk, pl, rw, rb, pr, run, out, slant, inf):
    """Node ``k + 1`` of the next right pixel (``out``), lane-wise: the cheapest of staying
    at ``k`` (``c1``), a left occlusion (``run + pl``), a right occlusion (``rb``) or a
    one-pixel jump (``c0``, ``p2``), plus the node cost minus the reward; the running minima
    ``run`` and ``rb`` take in ``c1``."""
    a = b.fadd(run, pl)
    jump = b.fadd(vmin(b, c0, p2), slant)
    best = vmin(b, vmin(b, c1, a), vmin(b, rb, jump))
    return {6: vmin(b, rb, b.fadd(c1, pr)), 8: vmin(b, run, c1),
            9: vmin(b, b.fsub(b.fadd(best, dk), rw), inf)}


@njit(cache=True, nogil=True)
def lane_backtrack(dn, geo, phi, pen_l, rew, pen_r, slant, row0, dmin, ints, sloc, disp,
                   state):
    """Walk back each active lane's path (:func:`_walk`) and decode it into its output row.
    ``ints`` (2, W) int32 and ``sloc`` (W,) uint8 are scratch."""
    match, dloc = ints[0], ints[1]
    for lane in range(LANES):
        if not geo[ACTIVE, lane]:
            continue
        r0, r1, x0, u1 = geo[R0, lane], geo[R1, lane], geo[X0, lane], geo[U1, lane]
        nx = u1 - r0
        if _walk(dn[r0:r1, :, lane], phi[r0:, :, lane], pen_l[r0:, lane], rew[r0:, lane],
                 pen_r[r0:, lane], slant, nx, match[:nx]):
            r = row0 + lane
            _store_row(match[:nx], geo[LA, lane], geo[LB, lane], r0, x0 - r0, dmin, dloc, sloc,
                       disp[r], state[r])


@njit(cache=True, inline="always")
def _walk(cost, phi, pen_l, rew, pen_r, slant, nx, match):
    """:func:`.aggregate._backtrack` on one lane, in the row's local coordinates: ``cost``
    (ny, nd) node costs, ``phi`` padded as there, ``pen_r[y]`` the right-occlusion penalty
    after right pixel ``y``. Same tests in the same order (the same tie-breaking)."""
    ny, nd = cost.shape
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
        before = phi[y + 1, k + 1] - cost[y, k] + rew[y + k]
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
            if 0 <= y2 < ny and phi[y2 + 1, k2 + 1] + pen_r[y2] == before:
                kb = k2
                break
        if kb < 0:  # cannot happen with exact costs; end the walk rather than loop
            return False
        y = x - kb
        k = kb
    return True
