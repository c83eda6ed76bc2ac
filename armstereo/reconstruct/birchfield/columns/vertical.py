"""The scanline programme on Birchfield-Tomasi costs smoothed along the columns first.

The paper's programme decides each scanline on its own, so neighbouring rows may settle on
different paths (streaks) wherever the row alone is ambiguous. Here each node cost
``C(r, xr, k)`` (right pixel ``xr`` of row ``r``, disparity index ``k``) is first smoothed
along its column as semi-global matching does along one line, from above and from below:

``L(r, xr, k) = C(r, xr, k) + min(L(r-1, xr, k), L(r-1, xr, k+-1) + p1, min_j L(r-1, xr, j)
+ p2) - min_j L(r-1, xr, j)``,

and the scanline programme (the match-sequence model, the occlusion rule and the slant steps
of :mod:`..window.aggregate`) then runs on ``L_down + L_up - C``: a row's path sees what the
rows above and below say at each disparity, with a smoothness price rather than a fixed window. All
values stay integers in float32 (doubled grey units), divided by ``q`` like
:mod:`..window.aggregate`'s sums so that the programme's equality-based backtrack stays exact.

Memory: the downward pass is kept, (H, W, nd) float32; the upward pass runs row by row and
each row is matched as soon as its smoothed costs are complete. Rows run on one thread.
"""

from __future__ import annotations

import numpy as np

from armstereo.reconstruct.birchfield.columns.rows import (
    row_backtrack,
    row_forward,
    row_slab,
    row_work_arrays,
)
from armstereo.reconstruct.birchfield.common.cost import INF, VARIATION_THRESHOLD, variation_flags
from armstereo.reconstruct.birchfield.common.jit import njit
from armstereo.reconstruct.birchfield.common.scanline import begin_row, store_row
from armstereo.reconstruct.birchfield.common.states import MAX_PIXEL_COST, NO_VARIATION_PENALTY
from armstereo.reconstruct.birchfield.window.aggregate import cost_divisor, fill_outside


@njit(cache=True, inline="always")
def _smooth_row(prev, cur, p1, p2, out):
    """One step of the column pass: ``out[xr, k]`` from the previous row's ``prev`` and this
    row's costs ``cur`` (all (W, nd), nd >= 2); branch-free inner loop so that it vectorises."""
    W, nd = cur.shape
    for xr in range(W):
        pv = prev[xr]
        c = cur[xr]
        o = out[xr]
        m = pv[0]
        for k in range(1, nd):
            m = min(m, pv[k])
        far = m + p2
        o[0] = c[0] + min(min(pv[0], far), pv[1] + p1) - m
        for k in range(1, nd - 1):
            o[k] = c[k] + min(min(pv[k], far), min(pv[k - 1], pv[k + 1]) + p1) - m
        o[nd - 1] = c[nd - 1] + min(min(pv[nd - 1], far), pv[nd - 2] + p1) - m


@njit(cache=True, nogil=True, fastmath=True)
def match_vertical(left3, right3, left, right, lmask, rmask, textured, dmin, nd, occ, rew,
                   slant, p1, p2, scale, q, disp, state, down, work):
    """Match every image row on column-smoothed costs (see the module doc).

    Arguments as :func:`..window.aggregate.match_image_aggregated` (``occ``, ``rew``, ``slant``:
    doubled per-pixel units, scaled by ``scale`` for the smoothed costs), plus ``p1``/``p2``
    (doubled units) and ``down``: an (H, W, nd) float32 work volume.
    """
    H, W = left.shape
    occ_s = np.float32(np.floor(occ * scale / q + 0.5))
    rew_s = np.float32(np.floor(rew * scale / q + 0.5))
    novar = np.float32(np.floor(NO_VARIATION_PENALTY * scale / q + 0.5))
    slant_s = np.float32(np.floor(slant * scale / q + 0.5)) if slant >= 0 else np.float32(INF)
    ring, raw, total, phi, vec, flags, ints, sloc = work
    cur, up_a, up_b = ring[0], ring[1], ring[2]
    bl = (vec[0, :W], vec[1, :W], vec[2, :W])
    br = (vec[3, :W], vec[4, :W], vec[5, :W])
    pen_l, rew_x, rbest = vec[6], vec[7], vec[8]
    a, dn = vec[9, :nd], vec[10, :nd]
    gl, gr = flags[0], flags[1]
    match, dloc = ints[0], ints[1]
    threshold, zero = np.int64(VARIATION_THRESHOLD), np.int64(0)
    forward, backward = np.bool_(True), np.bool_(False)
    f1, f2 = np.float32(p1), np.float32(p2)
    zero_rx = np.int64(0)
    for r in range(H):  # downward pass, kept
        if r == 0:
            row_slab(left, right, r, dmin, zero_rx, bl, br, raw, down[0])
        else:
            row_slab(left, right, r, dmin, zero_rx, bl, br, raw, cur)
            _smooth_row(down[r - 1], cur, f1, f2, down[r])
    prev_up, this_up = up_a, up_b
    for r in range(H - 1, -1, -1):  # upward pass; each row matched when complete
        row_slab(left, right, r, dmin, zero_rx, bl, br, raw, cur)
        if r == H - 1:
            for xr in range(W):
                for k in range(nd):
                    this_up[xr, k] = cur[xr, k]
        else:
            _smooth_row(prev_up, cur, f1, f2, this_up)
        dr = down[r]
        for xr in range(W):
            for k in range(nd):
                total[xr, k] = dr[xr, k] + this_up[xr, k] - cur[xr, k]
        prev_up, this_up = this_up, prev_up
        la, lb, r0, r1, x0, u1, ra, rb = begin_row(lmask[r], rmask[r], dmin, nd, disp[r],
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
        row_forward(slab, x_lo, nx, pen_l, gr, occ_s, novar, rew_x, slant_s, q, phi, rbest, a, dn)
        if row_backtrack(slab, x_lo, nx, phi, pen_l, gr, occ_s, novar, rew_x, slant_s, q,
                      match[:nx]):
            store_row(match[:nx], la, lb, r0, x_lo, dmin, dloc, sloc, disp[r], state[r])


def match_image_vertical(left: np.ndarray, right: np.ndarray, lmask: np.ndarray,
                         rmask: np.ndarray, dmin: int, nd: int, occ: int, rew: int, *,
                         p1: int, p2: int, scale: int, slant: int = -1,
                         textured: np.ndarray | None = None) -> dict[str, np.ndarray]:
    """Match (H, W) uint8 grey images on column-smoothed BT costs (doubled units: ``occ``,
    ``rew``, ``slant``, ``p1``, ``p2``; the penalties are multiplied by ``scale``, the
    smoothed costs' weight relative to one pixel's). Returns ``disp`` and ``state`` as
    :func:`..window.aggregate.match_image_aggregated`."""
    H, W = left.shape
    bound = 2 * (MAX_PIXEL_COST + p2)  # down + up - C, each pass at most C + p2
    q = cost_divisor(W, max(scale, -(-bound // MAX_PIXEL_COST)), occ)
    fl, fr = fill_outside(left, lmask), fill_outside(right, rmask)
    out = dict(disp=np.empty((H, W), np.int32), state=np.empty((H, W), np.uint8))
    if textured is None:
        textured = np.ones((H, W), np.bool_)
    match_vertical(left[:, :, None], right[:, :, None], fl, fr, lmask, rmask,
                   np.ascontiguousarray(textured, np.bool_), dmin, nd, occ, rew, slant,
                   p1, p2, scale, q, out["disp"], out["state"],
                   np.empty((H, W, nd), np.float32), row_work_arrays(W, nd, 1))
    return out
