"""The set-up of every block of rows for :mod:`.lanes`, in numpy for the whole image at once.

What each block needs before its programme runs (each row's valid runs and ranges, its
occlusion penalties and rewards, the reset of its output row) is a few whole-image array
operations here. It is not where the time goes (a few ms per image), but as a numba kernel
per block it was about a third of the matcher's first-run compile
(bench/results/coldstart.md).

The values are those of the kernels: the same integer geometry (:func:`.matcher.longest_run`,
:func:`.matcher.row_geometry`), the same intensity-variation flags (:func:`.cost.variation_flags`)
and the same float32 penalties, so the programme sees identical inputs.
"""

from __future__ import annotations

import numpy as np

from armstereo.reconstruct.birchfield.cost import VARIATION_THRESHOLD
from armstereo.reconstruct.birchfield.dp_pruned import BORDER, INVALID
from armstereo.reconstruct.birchfield.lanes import (
    ACTIVE,
    GEO,
    LA,
    LANES,
    LB,
    NOVAR,
    OCC,
    R0,
    R1,
    RA,
    RB,
    REW,
    U1,
    X0,
)


def longest_runs(mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(start, stop)`` (H,) int64 of each row's first longest run of True ((0, 0): none)."""
    H, W = mask.shape
    if mask.all():  # no rectification fill: every row is one run
        return np.zeros(H, np.int64), np.full(H, W, np.int64)
    idx = np.arange(W, dtype=np.int32)
    last_false = np.maximum.accumulate(np.where(mask, -1, idx), axis=1)
    run = idx - last_false  # length of the run ending at each pixel
    end = np.argmax(run, axis=1)  # the first pixel where the longest length is reached
    length = run[np.arange(H), end]
    has = length > 0
    return (np.where(has, end + 1 - length, 0).astype(np.int64),
            np.where(has, end + 1, 0).astype(np.int64))


def _varies(img: np.ndarray, lo: np.ndarray, hi: np.ndarray, forward: bool) -> np.ndarray:
    """(H, W) bool: the 3-pixel window at each pixel (``[x, x + 2]`` forward, ``[x - 2, x]``
    backward, cut at the row's segment ``[lo, hi)``) varies by >= VARIATION_THRESHOLD.
    Only pixels inside the segment are meaningful."""
    H, W = img.shape
    rows, cols = np.arange(H), np.arange(W)[None, :]
    # repeat the segment's edge pixel past it: plain shifted windows are then cut windows
    if (lo == 0).all() and (hi == W).all():  # whole rows: the image's own edges cut
        v = img
    elif forward:
        edge = img[rows, np.maximum(hi - 1, 0)][:, None]
        v = np.where(cols >= hi[:, None], edge, img)
    else:
        edge = img[rows, np.minimum(lo, W - 1)][:, None]
        v = np.where(cols < lo[:, None], edge, img)
    def shifted(a):  # a[x + 1] (forward) or a[x - 1], the last (first) pixel repeated
        return np.c_[a[:, 1:], a[:, -1:]] if forward else np.c_[a[:, :1], a[:, :-1]]

    b = shifted(v)
    c = shifted(b)
    mn = np.minimum(np.minimum(v, b), c)
    mx = np.maximum(np.maximum(v, b), c)
    return mx - mn >= VARIATION_THRESHOLD  # uint8: mx >= mn, no wrap


def block_setup(left: np.ndarray, right: np.ndarray, lmask: np.ndarray, rmask: np.ndarray,
                textured: np.ndarray, dmin: int, nd: int, pens: np.ndarray, disp: np.ndarray,
                state: np.ndarray) -> tuple:
    """Set up every block of :data:`.lanes.LANES` rows of the (H, W) uint8 grey images.

    Resets ``disp`` (-1) and ``state`` (INVALID, BORDER on the left valid run) in place.
    Returns ``(geo, pen_l, rew, pen_r, ranges)``: per block ``b``, ``geo[b]`` (GEO, LANES)
    int64, ``pen_l[b]``/``rew[b]`` (W + nd + 2, LANES) and ``pen_r[b]`` (W, LANES) float32
    as :func:`.lanes.lane_forward` and :func:`.lanes.lane_backtrack` read them, and
    ``ranges[b]`` the block's ``(x_begin, x_end)``.
    """
    H, W = lmask.shape
    nb = -(-H // LANES)
    la, lb = longest_runs(lmask)
    ra, rb = longest_runs(rmask)
    u0 = la - dmin
    u1 = np.minimum(lb - dmin, rb + nd - 1)
    r0 = np.maximum(ra, u0 - nd + 1)
    r1 = np.minimum(rb, u1)
    x0 = np.maximum(u0, r0)
    active = (r1 > r0) & (u1 > x0)
    disp[:] = -1
    c = np.arange(W, dtype=np.int32)[None, :]
    inside = (c >= la.astype(np.int32)[:, None]) & (c < lb.astype(np.int32)[:, None])
    np.subtract(np.uint8(INVALID), inside.view(np.uint8) * np.uint8(INVALID - BORDER),
                out=state)  # BORDER on the run

    # per-row bounds as int32 columns; an inactive row gets empty ranges (its values stay 0)
    def column(v, empty):
        return np.where(active, v, empty).astype(np.int32)[:, None]

    n_u = W + nd + 2
    u = np.arange(n_u, dtype=np.int32)[None, :]  # shifted left pixel (image column u + dmin)
    s0, s1 = column(r0, n_u), column(u1 + nd + 1, 0)  # the lane's span of left pixels
    e0, e1, rend = column(x0, n_u), column(u1, 0), column(u1, 0)
    gl = _left_columns(_varies(left, la, lb, True), dmin, n_u)
    occ, rew_s, novar = pens[OCC], pens[REW], pens[NOVAR]
    occ_nv = np.float32(occ + novar)
    span = (u >= s0) & (u < s1)
    pen_l = _select((u >= e0) & (u < e1) & gl, occ, occ_nv, span)
    rew = _select((u >= s0) & (u < rend) & _left_columns(textured, dmin, n_u), rew_s)
    gr = _varies(right, ra, rb, False)
    on_r = (c >= column(r0, W)) & (c < column(r1, 0))
    pen_r = _select(gr, occ, occ_nv, on_r)

    geo = np.zeros((nb * LANES, GEO), np.int64)
    for k, v in ((LA, la), (LB, lb), (R0, r0), (R1, r1), (X0, x0), (U1, u1), (RA, ra),
                 (RB, rb), (ACTIVE, active)):
        geo[:H, k] = np.where(active, v, 0)
    lo = np.where(active, r0, W)
    hi = np.where(active, r1, 0)
    pad = nb * LANES - H
    lo, hi = np.pad(lo, (0, pad), constant_values=W), np.pad(hi, (0, pad))
    ranges = np.stack([lo.reshape(nb, LANES).min(axis=1), hi.reshape(nb, LANES).max(axis=1)],
                      axis=1)
    return (np.ascontiguousarray(geo.reshape(nb, LANES, GEO).transpose(0, 2, 1)),
            _by_block(pen_l, nb), _by_block(rew, nb), _by_block(pen_r, nb), ranges)


def _left_columns(a: np.ndarray, dmin: int, n: int) -> np.ndarray:
    """(H, n) columns ``u + dmin`` of the (H, W) per-pixel ``a`` for shifted left pixels
    ``u < n``, clamped to ``W - 1``; a negative column wraps around, as the kernels' indexing
    does (numba's wraparound). Slices when ``dmin >= 0`` (a gather costs several times more)."""
    H, W = a.shape
    if dmin < 0:
        col = np.arange(n) + dmin
        return np.take(a, np.clip(np.where(col < 0, col + W, col), 0, W - 1), axis=1)
    out = np.empty((H, n), a.dtype)
    m = max(0, min(n, W - dmin))
    out[:, :m] = a[:, dmin:dmin + m]
    out[:, m:] = a[:, W - 1:]
    return out


def _select(cond: np.ndarray, a: np.float32, b: float = 0.0,
            where: np.ndarray | None = None) -> np.ndarray:
    """float32 ``a`` where ``cond``, else ``b``; 0 where ``where`` is False: the values (the
    same bits) of ``np.where``, by integer arithmetic on the bit patterns, which is several
    times faster than ``np.where`` with scalars on irregular conditions (no branches)."""
    ia, ib = np.float32(a).view(np.uint32), np.float32(b).view(np.uint32)
    bits = cond.astype(np.uint32)
    bits *= ia ^ ib
    bits ^= ib
    if where is not None:
        bits *= where
    return bits.view(np.float32)


def _by_block(a: np.ndarray, nb: int) -> np.ndarray:
    """(H, n) per-row values as (nb, n, LANES) contiguous blocks (rows past H zero)."""
    H, n = a.shape
    out = np.zeros((nb * LANES, n), a.dtype)
    out[:H] = a
    return np.ascontiguousarray(out.reshape(nb, LANES, n).transpose(0, 2, 1))
