"""All scanlines of a rectified pair on the paper's single-pixel costs, rows on threads.

The route of the options the default window path does not take: colour costs
(``color="sum"``/``"max"``: :func:`.dp_exact.scanline_dp_exact`) and the reference code's
pruned search (``search="pruned"``: :func:`.dp_pruned.scanline_dp`; ``DP_FULL``, its unpruned
form, is the tests' oracle). Each row is set up and decoded as every route does it
(:mod:`..common.scanline`: the longest valid runs, the disparity window, the decoding).

Rows are independent; :func:`match_image` runs the compiled row loop (``nogil``) on a few
Python threads over interleaved rows, not on numba's parallel layer (``prange``): OpenMP
workers keep spinning for a while after a parallel region and can slow the OpenCV stage that
follows on a small machine (bench/stereo_threads.py); these threads end with the call.
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor

import numba
import numpy as np

from armstereo.reconstruct.birchfield.common.cost import (
    INF,
    VARIATION_THRESHOLD,
    dissimilarity_table,
    interval_bounds,
    variation_flags,
)
from armstereo.reconstruct.birchfield.common.jit import njit
from armstereo.reconstruct.birchfield.common.scanline import begin_row, store_row
from armstereo.reconstruct.birchfield.paper.dp_exact import scanline_dp_exact
from armstereo.reconstruct.birchfield.paper.dp_pruned import scanline_dp

DP_EXACT = 0  # exact O(n nd) programme
DP_PRUNED = 1  # reference code's pruned search
DP_FULL = 2  # unpruned push search, O(n nd^2): an oracle


@njit(cache=True, inner=True)
def _row_bounds(left, right, la, lb, ra, rb, r0, r1, x0, u1, dmin, gl, gr):
    """Interval bounds (C, n) and intensity-variation flags of one row, local coordinates:
    right pixel ``r0 + y`` is local ``y``; left pixel ``r0 + dmin + x`` is local ``x``."""
    C = left.shape[1]
    ny = r1 - r0
    nx = u1 - r0
    x_lo = x0 - r0
    lv = np.zeros((C, nx), np.int32)
    lmin = np.zeros((C, nx), np.int32)
    lmax = np.zeros((C, nx), np.int32)
    rv = np.empty((C, ny), np.int32)
    rmin = np.empty((C, ny), np.int32)
    rmax = np.empty((C, ny), np.int32)
    interval_bounds(left, la, lb, x0 + dmin, u1 + dmin, lv, lmin, lmax, x_lo)
    interval_bounds(right, ra, rb, r0, r1, rv, rmin, rmax, 0)
    gl[:] = False
    variation_flags(left, la, lb, x0 + dmin, u1 + dmin, VARIATION_THRESHOLD, True, gl, x_lo)
    variation_flags(right, ra, rb, r0, r1, VARIATION_THRESHOLD, False, gr, 0)
    return lv, lmin, lmax, rv, rmin, rmax


@njit(cache=True, nogil=True)
def match_rows(left, right, lmask, rmask, rows, dmin, nd, occ, rew, combine_max, disp, state):
    """Match the rows ``rows`` of (H, W, C) uint8 images with the exact programme.

    Fills (H, W) int32 ``disp`` with the window index ``k`` (disparity ``dmin + k``, -1 = none)
    and uint8 ``state`` (MATCHED / OCCLUDED / BORDER / INVALID of :mod:`..common.states`).
    """
    W = left.shape[1]
    phi = np.empty((W, nd), np.float32)  # work array of scanline_dp_exact
    gl = np.empty(W, np.bool_)
    gr = np.empty(W, np.bool_)
    match = np.empty(W, np.int32)
    dloc = np.empty(W, np.int32)
    sloc = np.empty(W, np.uint8)
    for r in rows:
        la, lb, r0, r1, x0, u1, ra, rb = begin_row(lmask[r], rmask[r], dmin, nd, disp[r],
                                                    state[r])
        if r1 <= r0 or u1 <= x0:
            continue
        ny, nx, x_lo = r1 - r0, u1 - r0, x0 - r0
        b = _row_bounds(left[r], right[r], la, lb, ra, rb, r0, r1, x0, u1, dmin, gl[:nx],
                        gr[:ny])
        cost = scanline_dp_exact(b[0], b[1], b[2], b[3], b[4], b[5], x_lo, combine_max,
                                 gl[:nx], gr[:ny], occ, rew, phi[:ny], match[:nx])
        if cost < INF:
            store_row(match[:nx], la, lb, r0, x_lo, dmin, dloc, sloc, disp[r], state[r])


@njit(cache=True, nogil=True)
def match_rows_search(left, right, lmask, rmask, rows, dmin, nd, occ, rew, combine_max,
                      prune, disp, state):
    """:func:`match_rows` with the search programme of :mod:`.dp_pruned`: the reference code's
    pruned search, or (``prune=False``) the unpruned O(n nd^2) one. A separate function so
    that the default path does not compile it."""
    W = left.shape[1]
    gl = np.empty(W, np.bool_)
    gr = np.empty(W, np.bool_)
    match = np.empty(W, np.int32)
    dloc = np.empty(W, np.int32)
    sloc = np.empty(W, np.uint8)
    for r in rows:
        la, lb, r0, r1, x0, u1, ra, rb = begin_row(lmask[r], rmask[r], dmin, nd, disp[r],
                                                    state[r])
        if r1 <= r0 or u1 <= x0:
            continue
        ny, nx, x_lo = r1 - r0, u1 - r0, x0 - r0
        b = _row_bounds(left[r], right[r], la, lb, ra, rb, r0, r1, x0, u1, dmin, gl[:nx],
                        gr[:ny])
        dis = np.empty((ny, nd), np.int32)
        dissimilarity_table(b[0], b[1], b[2], b[3], b[4], b[5], x_lo, combine_max, dis)
        cost = scanline_dp(dis, gl[:nx], gr[:ny], occ, rew, prune, np.empty((ny, nd), np.int32),
                           np.empty((ny, nd), np.int16), match[:nx])
        if cost < INF:
            store_row(match[:nx], la, lb, r0, x_lo, dmin, dloc, sloc, disp[r], state[r])


def match_image(left: np.ndarray, right: np.ndarray, lmask: np.ndarray, rmask: np.ndarray,
                dmin: int, nd: int, occ: int, rew: int, *, combine_max: bool = False,
                mode: int = DP_EXACT, threads: int | None = None):
    """Scanline-match a pair; returns ``(disp_index, state)`` (see :func:`match_rows`).

    ``mode``: DP_EXACT, DP_PRUNED or DP_FULL.

    ``threads`` defaults to ``numba.get_num_threads()``, so ``numba.set_num_threads(1)``
    makes the whole matcher single-threaded.
    """
    H, W = left.shape[:2]
    disp = np.empty((H, W), np.int32)
    state = np.empty((H, W), np.uint8)
    n = max(1, min(H, threads or numba.get_num_threads()))
    jobs = [np.arange(i, H, n, dtype=np.int64) for i in range(n)]
    if mode == DP_EXACT:
        rows_fn, extra = match_rows, ()
    else:
        rows_fn, extra = match_rows_search, (mode == DP_PRUNED,)
    args = (left, right, lmask, rmask)
    params = (dmin, nd, occ, rew, combine_max, *extra, disp, state)
    if n == 1:
        rows_fn(*args, jobs[0], *params)
    else:
        with ThreadPoolExecutor(n) as pool:
            for f in [pool.submit(rows_fn, *args, rows, *params) for rows in jobs]:
                f.result()
    return disp, state
