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
same float32 operations in the same order as the one-row programme did before (main up to
commit 860bbe9, ``aggregate.match_block``): identical costs, identical paths, which
tests/data/birchfield_rows holds the proof of. The backtrack stays per lane (scalar).

The programme of one row, on node costs ``c(x, k)`` (window sums of BT dissimilarities, INF
where the left pixel ``x + k`` is outside the row's range), ``phi(x, k)`` being the cheapest
path into node ``(x, k)``: ``phi(r0, k) = C0 + c(r0, k)``, and ``phi(x + 1, k)`` is the least
of ``phi(x, k)`` (both pixels advance), ``phi(x, k') + pen_l(x + 1 + k)`` for ``k' < k``
(left pixels skipped), ``phi(x', x + k - x') + pen_r(x')`` for ``x' < x`` (right pixels
skipped; ``rbest`` keeps its running minimum per left pixel) and ``min(phi(x, k - 1),
phi(x - 1, k + 1)) + slant`` (one-pixel steps), plus ``c(x + 1, k)`` minus the reward,
clamped to INF. The backtrack re-derives each step from ``phi`` by equality, in a fixed
order of preference (no jump, slant steps, left skip with the smallest ``k'``, right skip
with the largest ``k``): exact float32 integers make the equalities hold.

The kernels are small and called from Python per block (:func:`.aggregate.match_image_aggregated`):
numba then compiles each once, instead of re-optimising every callee inside one large kernel
(the first run's compile time, bench/results/coldstart.md).
"""

from __future__ import annotations

import numpy as np

from armstereo.reconstruct.birchfield.common.cost import INF
from armstereo.reconstruct.birchfield.common.jit import njit
from armstereo.reconstruct.birchfield.common.minmax import max2, min2
from armstereo.reconstruct.birchfield.common.states import (
    BORDER,
    C0,
    MATCHED,
    OCCLUDED,
    VALID_BELOW,
)
from armstereo.reconstruct.birchfield.window.simd import LANES, lanewise, vfloor, vmax, vmin

# rows of the (GEO, LANES) int64 geometry of a block: the valid runs of the left
# (la, lb) and right (ra, rb) rows, the programme's ranges (r0, r1, x0, u1), active flag
GEO = 9
LA, LB, R0, R1, X0, U1, RA, RB, ACTIVE = range(GEO)
OCC, REW, NOVAR, SLANT = range(4)  # the scaled penalties in ``pens``


@njit(cache=True, nogil=True, fastmath=True)
def lane_forward(row0, rx, ry, dmin, q, geo, x_begin, x_end, pen_l, rew, pen_r, slant, costs,
                 phi, rbest, run):
    """The forward pass of the programme (module doc) for every lane in lockstep, on node
    costs computed as it goes (:func:`_node_costs`): an image's worth of them, per lane, would
    not stay in the cache between two passes.

    Node ``(x, k)`` of a lane is
    ``phi[x + 1, k + 1, lane]`` (row 0 and columns 0 and ``nd + 1`` stay INF);
    ``rbest[u, lane]``: the running minimum of right-occlusion costs into shifted left pixel
    ``u``; ``run`` (LANES,) float32 scratch. ``slant``: the scaled one-pixel-jump penalty
    (INF: none). ``costs``: ``(bounds, col, lims, ring, d)``, the image's BT intervals
    (:func:`image_bounds`) and work arrays: ``col`` (nd, nj), ``lims`` (2, LANES), ``ring``
    (2 rx + 1, nd, LANES), ``d`` (W, nd, LANES) float32 (the node costs of every right
    pixel: the backtrack reads them back).
    """
    nd = phi.shape[1] - 2
    inf = np.float32(INF)
    bounds, col, lims, ring, d = costs
    for lane in range(LANES):  # float32 copies, for comparing in float32 vectors
        lims[0, lane] = geo[X0, lane]
        lims[1, lane] = geo[U1, lane]
    b = (bounds, row0)
    for c in range(x_begin - rx, x_begin + rx):
        _column_sums(b, c, dmin, ry, col, ring)
    _node_costs(b, x_begin, rx, ry, dmin, q, lims, col, ring, d[x_begin])
    for u in range(x_begin, x_end + nd):
        for lane in range(LANES):
            rbest[u, lane] = inf
    for x in range(x_begin, x_end):
        here = d[x]
        for lane in range(LANES):
            if geo[ACTIVE, lane] and geo[R0, lane] == x:
                start_lane(here, lane, phi[x], phi[x + 1], rbest[x:x + nd])
        if x + 1 < x_end:
            there = d[x + 1]
            _node_costs(b, x + 1, rx, ry, dmin, q, lims, col, ring, there)
            _step(there, phi[x], phi[x + 1], phi[x + 2], pen_l[x + 1:x + 1 + nd],
                  rew[x + 1:x + 1 + nd], pen_r[x], rbest[x:x + nd], slant, run)


@njit(cache=True, inline="always")
def _column_sums(b, c, dmin, ry, col, ring):
    """BT dissimilarities of right column ``c`` (clamped to the image) summed over each
    lane's rows (:func:`_vertical_sums`), into ``ring[c mod len(ring)]``."""
    W = b[0].shape[1]
    _vertical_sums(b, min2(W - 1, max2(0, c)), dmin, ry, col, ring[c % ring.shape[0]])


@njit(cache=True, inner=True)
def _node_costs(b, x, rx, ry, dmin, q, lims, col, ring, out):
    """Node costs of right pixel ``x``, ``out[k, lane]``: the BT dissimilarities summed over
    the ``(2 ry + 1) x (2 rx + 1)`` window (rows and columns clamped to the image), divided by
    ``q`` (floor), INF where ``x + k`` is outside the lane's ``[x0, u1)``. ``ring`` holds the
    column sums of ``x - rx - 1 .. x + rx - 1`` on entry, of ``x - rx .. x + rx`` on return.
    Every sum is of integers below float32's exact range, so its order does not change it."""
    if rx == 0:  # one column (the default window): its sums are the costs, no ring
        _vertical_sums(b, x, dmin, ry, col, out)
    else:
        _column_sums(b, x + rx, dmin, ry, col, ring)
        for k in range(out.shape[0]):
            _copy(((ring, 0, k, 0), (out, k, 0)), ())
            for s in range(1, ring.shape[0]):
                _add(((ring, s, k, 0), (out, k, 0)), ())
    _finish(out, x, lims, q)


@njit(cache=True, nogil=True)
def image_bounds(left_t, right_t, bounds):
    """Doubled value and min/max of the half-samples (BT intervals, :mod:`..common.cost`) of every
    pixel of the filled grey images, transposed so that a block's rows are contiguous:
    ``bounds[i, x, j]``, ``i`` 0..2 left, 3..5 right. ``left_t``/``right_t`` (W, nj) uint8:
    the images transposed, ``[x, j]`` their row ``j - ry`` (clamped to the image; columns past
    ``H + 2 ry`` pad the last block's vectors): the loop over ``j`` then reads and writes
    contiguously, and LLVM vectorises it. The two images in one loop (a tuple indexed by the
    side), not the loop inlined twice: half the code to compile on the first run."""
    W = left_t.shape[0]
    images = (left_t, right_t)
    for side in range(2):
        img = images[side]
        for x in range(W):
            c, before, after = img[x], img[max2(0, x - 1)], img[min2(W - 1, x + 1)]
            value, lo, hi = bounds[3 * side, x], bounds[3 * side + 1, x], bounds[3 * side + 2, x]
            for j in range(c.shape[0]):
                v = np.float32(c[j])
                a = np.float32(2) * v
                p = np.float32(before[j]) + v
                n = v + np.float32(after[j])
                value[j] = a
                lo[j] = min2(a, min2(p, n))
                hi[j] = max2(a, max2(p, n))


@njit(cache=True, inner=True)
def _vertical_sums(bj, x, dmin, ry, col, out):
    """``out[k, lane]``: BT dissimilarity of right pixel ``x`` and left pixel ``x + dmin + k``
    (the last column past the right edge) summed over the ``2 ry + 1`` rows around the lane;
    ``bj``: the image's intervals and the block's first column in them;
    ``col`` (nd, nj) is scratch. Two passes: a vector load across two recent stores waits for
    them to reach the cache, so the rows are all stored before the shifted loads begin."""
    b, j0 = bj
    W = b.shape[1]
    zero = np.float32(0.0)
    for j in range(j0, j0 + col.shape[1], LANES):  # k inner: the right pixel's loads stay put
        for k in range(out.shape[0]):
            u = min2(W - 1, x + dmin + k)
            _bt(((b, 0, u, j), (b, 1, u, j), (b, 2, u, j), (b, 3, x, j), (b, 4, x, j),
                 (b, 5, x, j), (col, k, j - j0)), (zero,))
    for k in range(out.shape[0]):
        _copy(((col, k, 0), (out, k, 0)), ())
        for t in range(1, 2 * ry + 1):
            _add(((col, k, t), (out, k, 0)), ())


@lanewise
def _bt(b, lv, lmin, lmax, rv, rmin, rmax, out, zero):
    """BT dissimilarity, lane-wise, of left values ``lv`` in ``[lmin, lmax]`` and right values
    ``rv`` in ``[rmin, rmax]``: ``min(max(0, lv - rmax, rmin - lv), max(0, rv - lmax,
    lmin - rv))``."""
    d_l = vmax(b, zero, vmax(b, b.fsub(lv, rmax), b.fsub(rmin, lv)))
    d_r = vmax(b, zero, vmax(b, b.fsub(rv, lmax), b.fsub(lmin, rv)))
    return {6: vmin(b, d_l, d_r)}


@lanewise
def _copy(b, src, dst):
    return {1: src}


@lanewise
def _add(b, src, dst):
    return {1: b.fadd(dst, src)}


@njit(cache=True, inline="always")
def _finish(out, x, lims, q):
    """Node costs of right pixel ``x`` in place: divided by ``q``, INF outside ``[x0, u1)``."""
    inf = np.float32(INF)
    iq = np.float32(1.0 / q)
    for k in range(out.shape[0]):
        u = np.float32(x + k)
        if q == 1:
            _mask(((out, k, 0), (lims, 0, 0), (lims, 1, 0)), (u, inf))
        else:
            _mask_divided(((out, k, 0), (lims, 0, 0), (lims, 1, 0)), (u, inf, iq))


@lanewise
def _mask(b, cost, x0, u1, u, inf):
    """``cost`` where ``x0 <= u < u1``, else ``inf``."""
    ok = b.and_(b.fcmp_ordered("<=", x0, u), b.fcmp_ordered("<", u, u1))
    return {0: b.select(ok, cost, inf)}


@lanewise
def _mask_divided(b, cost, x0, u1, u, inf, iq):
    """:func:`_mask` of ``floor(cost * iq)``."""
    ok = b.and_(b.fcmp_ordered("<=", x0, u), b.fcmp_ordered("<", u, u1))
    return {0: b.select(ok, vfloor(b, b.fmul(cost, iq)), inf)}


@njit(cache=True, inline="always")
def start_lane(d, lane, before, first, rbest):
    """A lane's first right pixel: nothing before it, its nodes start at ``C0`` plus their
    cost, no right occlusion yet (the one-row programme's initial state)."""
    inf = np.float32(INF)
    for c in range(before.shape[0]):
        before[c, lane] = inf
    for k in range(d.shape[0]):
        first[k + 1, lane] = min2(np.float32(C0) + d[k, lane], inf)
        rbest[k, lane] = inf


@njit(cache=True, inline="always")
def _step(d, prev, cur, nxt, pen_l, rew, pen_r, rbest, slant, run):
    """Nodes of the next right pixel from the current (``cur``) and previous (``prev``) ones;
    the same operations, in the same order, as one step of the one-row programme, whose
    running minimum over ``k`` (left occlusions) is ``run`` here, one per lane."""
    inf = np.float32(INF)
    for lane in range(LANES):
        run[lane] = inf
    for k in range(d.shape[0]):
        _node_update(((cur, k, 0), (cur, k + 1, 0), (prev, k + 2, 0), (d, k, 0), (pen_l, k, 0),
                      (rew, k, 0), (rbest, k, 0), pen_r, run, (nxt, k + 1, 0)), (slant, inf))


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
def lane_backtrack(geo, phi, nodes, pen_l, rew, pen_r, slant, dmin, row0, ints, sloc, disp,
                   state):
    """Walk back each active lane's path (:func:`_walk`), decoding it into its output row as
    it goes. ``nodes``: the node costs of the forward pass (its ``d``); ``ints`` (2, W + nd)
    int32 (a lane has up to W + nd - 1 left pixels) and ``sloc`` (W + nd,) uint8 are scratch.

    The decoding is :func:`..common.scanline.store_row`'s (the reference code's policy):
    matched pixels get their ``k``, left-occluded runs the ``k`` of the match before them,
    pixels before the first match or after the last its ``k`` and BORDER, and the row's
    valid pixels outside the programme's range the nearest decoded disparity."""
    W = disp.shape[1]
    dloc = ints[1]
    for lane in range(LANES):
        if not geo[ACTIVE, lane]:
            continue
        la, lb = geo[LA, lane], geo[LB, lane]
        r0, r1, x0, u1 = geo[R0, lane], geo[R1, lane], geo[X0, lane], geo[U1, lane]
        nx = u1 - r0
        off = r0 + dmin  # image column of local left pixel 0
        x_lo = x0 - r0
        lo = off + x_lo
        r = row0 + lane
        drow, srow = disp[r], state[r]
        walk = (nodes[r0:, :, lane], r1 - r0, phi[r0:, :, lane], pen_l[r0:, lane],
                rew[r0:, lane], pen_r[r0:, lane], slant)
        if nx <= W:  # always with dmin >= 0: decode straight into the row
            if not _walk(*walk, x_lo, drow[lo:off + nx], srow[lo:off + nx]):
                continue
            end = off + nx
            first, last = drow[lo], drow[end - 1]
        else:
            # a negative dmin can give a lane more left pixels than the image has columns:
            # only the first W are decoded, as if the sequence ended there (the pixels after
            # its last match below W become BORDER; with none, nothing is decoded)
            if not _walk(*walk, np.int64(0), dloc[:nx], sloc[:nx]):
                continue
            m = W - 1
            while m >= 0 and sloc[m] != MATCHED:
                m -= 1
            for x in range(m + 1, W):
                sloc[x] = BORDER
                if m < 0:
                    dloc[x] = -1
            for x in range(x_lo, W):
                drow[off + x] = dloc[x]
                srow[off + x] = sloc[x]
            end = off + W
            first, last = dloc[x_lo], dloc[W - 1]
        for c in range(la, min2(lo, W)):
            drow[c] = first
        for c in range(end, min2(lb, W)):
            drow[c] = last


@njit(cache=True, inner=True)
def _walk(nodes, ny, phi, pen_l, rew, pen_r, slant, x_lo, disp, state):
    """The backtrack of one lane (module doc), in the row's local coordinates: ``nodes[y, k]``
    the node costs, ``phi`` padded as in the forward pass, ``pen_r[y]``
    the right-occlusion penalty after right pixel ``y``. Same tests in the same order (the
    same tie-breaking). Decodes the path into ``disp``/``state``, the left pixels ``x_lo ..
    x_lo + len(disp) - 1`` (local): the path visits the left pixels from the right, so each
    match fills the unmatched run after it. False (outputs as they were) if there is no
    path."""
    nd = phi.shape[1] - 2
    nx = x_lo + disp.shape[0]
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
    hi = nx  # the pixels from hi on are decoded
    while True:
        xl = y + k
        # the unmatched pixels after this match: occluded, or BORDER after the last match
        after = OCCLUDED if hi < nx else BORDER
        for x in range(max2(xl + 1, x_lo), hi):
            disp[x - x_lo] = k
            state[x - x_lo] = after
        if xl >= x_lo:
            disp[xl - x_lo] = k
            state[xl - x_lo] = MATCHED
        hi = min2(hi, xl)
        if y == 0:
            break
        before = phi[y + 1, k + 1] - nodes[y, k] + rew[y + k]
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
        if kb < 0:  # cannot happen with exact costs: undo the decoding, end the walk
            for x in range(disp.shape[0]):
                disp[x] = -1
                state[x] = BORDER
            return False
        y = x - kb
        k = kb
    for x in range(x_lo, hi):  # before the first match: its disparity, BORDER
        disp[x - x_lo] = k
        state[x - x_lo] = BORDER
    return True
