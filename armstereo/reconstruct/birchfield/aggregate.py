"""The scanline programme on window-summed dissimilarities, plus one-pixel slant steps.

The paper matches each scanline on single-pixel dissimilarities, so neighbouring rows decide
independently (streaks) and every noise-level cost difference counts. Here the node cost of
``(right pixel xr, disparity index k)`` is the *sum* of the Birchfield-Tomasi dissimilarities
over a ``(2 ry + 1) x (2 rx + 1)`` window around it at the same disparity; the match-sequence
model, the occlusion rule (jumps only next to intensity variation) and the exact programme are
those of :mod:`.dp_fast`, with the penalties scaled by the window's pixel count so that they
keep their per-pixel meaning. A one-pixel disparity step may also cost a smaller ``slant``
penalty, without intensity variation (a slanted surface rather than an occlusion).

Rows are processed in a contiguous block: a ring of ``2 ry + 1`` horizontally summed rows and
their running vertical sum give each row's (W, nd) cost slab with a few additions per entry.
Pixels outside the validity masks take part in the sums with the edge-replicated values the
caller fills in (a row's programme itself only uses its valid run, as in :mod:`.matcher`).

The reward for a match can be withheld per left pixel (``textured``): matching a featureless
pixel then gains nothing, so the programme has no reason to bend its path through a black gap
at a wrong disparity and declare the textured pixels beside it occluded.

Costs are integer sums in float32, divided by ``q`` (floor) when a row could otherwise exceed
float32's exact integers: the programme's equality-based backtrack needs exact arithmetic.
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor

import numpy as np

from armstereo.reconstruct.birchfield.cost import INF, VARIATION_THRESHOLD, variation_flags
from armstereo.reconstruct.birchfield.dp_exact import EXACT_BELOW, MAX_PIXEL_COST, VALID_BELOW
from armstereo.reconstruct.birchfield.dp_pruned import C0, NO_VARIATION_PENALTY
from armstereo.reconstruct.birchfield.jit import njit
from armstereo.reconstruct.birchfield.matcher import _begin_row, _store_row

SUB_R = 2  # sub-pixel window radius


def cost_divisor(width: int, window_pixels: int, occ: int) -> int:
    """Smallest ``q`` keeping every path cost of a row exact in float32 (see the module doc)."""
    top = width * window_pixels * MAX_PIXEL_COST + 2 * (occ + NO_VARIATION_PENALTY) * (
        window_pixels) + C0
    return max(1, -(-top // (EXACT_BELOW // 2)))


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
def _row_slab(left, right, r, dmin, rx, lb, rbnd, raw, out):
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
def _forward(cost, x_lo, nx, pen_l, gr, occ, novar, rew, slant, q, phi, rbest, a, dn):
    """The exact programme of :mod:`.dp_fast` on a (ny, nd) slab of summed costs, plus
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
def _backtrack(cost, x_lo, nx, phi, pen_l, gr, occ, novar, rew, slant, q, match):
    """Walk back from the cheapest node at the last left pixel (ties: largest k); as in
    :func:`.dp_exact._backtrack`, each step re-derived from the padded ``phi``
    of :func:`_forward` (preference: no jump, one-pixel jumps, occlusions)."""
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


@njit(cache=True, inline="always")
def _slide(total, slab, sign):
    """``total += sign * slab`` as plain loops (numba's array expressions allocate here)."""
    W, nd = total.shape
    f = np.float32(sign)
    for x in range(W):
        t = total[x]
        a = slab[x]
        for k in range(nd):
            t[k] += f * a[k]


@njit(cache=True, nogil=True, fastmath=True)
def match_block(left3, right3, left, right, lmask, rmask, textured, r_begin, r_end, dmin, nd,
                occ, rew, slant, rx, ry, q, disp, state, work):
    """Match image rows ``r_begin .. r_end - 1`` on aggregated costs.

    ``left3``/``right3``: (H, W, 1) uint8 grey images as given (intensity-variation flags);
    ``left``/``right``: (H, W) uint8 grey images filled outside the masks (costs). ``occ`` and
    ``rew``: doubled per-pixel penalty and reward. Outputs, indexed by left image pixel:
    ``disp``/``state`` as :func:`armstereo.reconstruct.birchfield.matcher.match_rows`.
    ``work``: the work arrays of :func:`_work_arrays`.
    """
    H, W = left.shape
    n = ry * 2 + 1
    npix = n * (2 * rx + 1)
    occ_s = np.float32(np.floor(occ * npix / q + 0.5))
    rew_s = np.float32(np.floor(rew * npix / q + 0.5))
    novar = np.float32(np.floor(NO_VARIATION_PENALTY * npix / q + 0.5))
    slant_s = np.float32(np.floor(slant * npix / q + 0.5)) if slant >= 0 else np.float32(INF)
    ring, raw, total, phi, vec, flags, ints, sloc = work
    bl = (vec[0, :W], vec[1, :W], vec[2, :W])
    br = (vec[3, :W], vec[4, :W], vec[5, :W])
    pen_l, rew_x, rbest = vec[6], vec[7], vec[8]
    a, dn = vec[9, :nd], vec[10, :nd]
    gl, gr = flags[0], flags[1]
    match, dloc = ints[0], ints[1]
    # np.int64/np.bool_: plain constants would be typed as literals, and each literal value
    # compiles its own copy of the called kernel
    threshold, zero = np.int64(VARIATION_THRESHOLD), np.int64(0)
    forward, backward = np.bool_(True), np.bool_(False)
    for j in range(-ry, ry + 1):
        rr = r_begin + j
        s = (rr - r_begin + n) % n
        _row_slab(left, right, min(H - 1, max(0, rr)), dmin, rx, bl, br, raw, ring[s])
        _slide(total, ring[s], 1)
    for r in range(r_begin, r_end):
        if r > r_begin:
            s = (r + ry - r_begin + n) % n
            _slide(total, ring[s], -1)
            _row_slab(left, right, min(H - 1, r + ry), dmin, rx, bl, br, raw, ring[s])
            _slide(total, ring[s], 1)
        la, lb, r0, r1, x0, u1, ra, rb = _begin_row(lmask[r], rmask[r], dmin, nd, disp[r],
                                                    state[r])
        if r1 <= r0 or u1 <= x0:
            continue
        nx, x_lo = u1 - r0, x0 - r0
        for x in range(W):
            gl[x] = False
        variation_flags(left3[r], la, lb, x0 + dmin, u1 + dmin, threshold, forward, gl, x_lo)
        variation_flags(right3[r], ra, rb, r0, r1, threshold, backward, gr, zero)
        for i in range(nx + nd + 1):
            pen_l[i] = occ_s if i < nx and gl[i] else occ_s + novar
            rew_x[i] = rew_s if i < nx and textured[r, r0 + dmin + i] else np.float32(0.0)
        slab = total[r0:r1]
        _forward(slab, x_lo, nx, pen_l, gr, occ_s, novar, rew_x, slant_s, q, phi, rbest, a, dn)
        if _backtrack(slab, x_lo, nx, phi, pen_l, gr, occ_s, novar, rew_x, slant_s, q,
                      match[:nx]):
            _store_row(match[:nx], la, lb, r0, x_lo, dmin, dloc, sloc, disp[r], state[r])


def _work_arrays(W: int, nd: int, ry: int) -> tuple:
    """Work arrays of one :func:`match_block` call, allocated here rather than in the kernel:
    every array type a kernel creates compiles its own allocation code (numba's cold start).

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


def fill_outside(grey: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """Copy of an (H, W) image whose pixels left/right of each row's valid span repeat the
    span's edge pixels (so window sums near a mask edge see plausible values, not black)."""
    H, W = grey.shape
    has = mask.any(axis=1)
    a = np.where(has, np.argmax(mask, axis=1), 0)
    b = np.where(has, W - 1 - np.argmax(mask[:, ::-1], axis=1), W - 1)
    cols = np.clip(np.arange(W)[None, :], a[:, None], b[:, None])
    return np.ascontiguousarray(np.take_along_axis(grey, cols, axis=1))


def match_image_aggregated(left: np.ndarray, right: np.ndarray, lmask: np.ndarray,
                           rmask: np.ndarray, dmin: int, nd: int, occ: int, rew: int, rx: int,
                           ry: int, *, slant: int = -1, textured: np.ndarray | None = None,
                           threads: int = 1) -> dict[str, np.ndarray]:
    """Match (H, W) uint8 grey images on ``(2 ry + 1) x (2 rx + 1)`` aggregated costs.

    Returns the maps of :func:`match_block` by name (``disp``, ``state``). Rows run in
    ``threads`` contiguous blocks.
    """
    H, W = left.shape
    q = cost_divisor(W, (2 * rx + 1) * (2 * ry + 1), occ)
    fl, fr = fill_outside(left, lmask), fill_outside(right, rmask)
    out = dict(disp=np.empty((H, W), np.int32), state=np.empty((H, W), np.uint8))
    if textured is None:
        textured = np.ones((H, W), np.bool_)
    args = (left[:, :, None], right[:, :, None], fl, fr, lmask, rmask,
            np.ascontiguousarray(textured, np.bool_))
    maps = (out["disp"], out["state"])
    n = max(1, min(H, threads))
    cuts = np.linspace(0, H, n + 1).round().astype(int)
    if n == 1:
        match_block(*args, 0, H, dmin, nd, occ, rew, slant, rx, ry, q, *maps,
                    _work_arrays(W, nd, ry))
    else:
        with ThreadPoolExecutor(n) as pool:
            jobs = [pool.submit(match_block, *args, int(cuts[i]), int(cuts[i + 1]), dmin, nd,
                                occ, rew, slant, rx, ry, q, *maps, _work_arrays(W, nd, ry))
                    for i in range(n)]
            for job in jobs:
                job.result()
    return out
