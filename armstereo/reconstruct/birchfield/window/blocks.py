"""The set-up of every block of rows for :mod:`.lanes`, for the whole image at once.

What each block needs before its programme runs (each row's valid runs and ranges, its
occlusion penalties and rewards, the reset of its output row) is a few whole-image array
operations here, and one small kernel (:func:`lane_penalties`) that writes the per-pixel
penalties and rewards straight into the lanes' layout: in numpy, the selects and the
transposes to that layout were ~2 ms of tsukuba's 7 ms matcher. The kernel is kept small
(one loop nest, five arguments: ~0.3 s of first-run compile); the old per-block set-up
kernel, with the geometry and the flags inlined, was a third of the matcher's compile
(bench/results/coldstart.md, dp_lanes.md).

The values are those of the kernels: the same integer geometry
(:func:`..common.scanline.longest_run`, :func:`..common.scanline.row_geometry`), the same
intensity-variation flags (:func:`..common.cost.variation_flags`) and the same float32
penalties, so the programme sees identical inputs.
"""

from __future__ import annotations

import cv2
import numpy as np

from armstereo.reconstruct.birchfield.common.cost import VARIATION_THRESHOLD
from armstereo.reconstruct.birchfield.common.jit import njit
from armstereo.reconstruct.birchfield.common.minmax import max2, min2
from armstereo.reconstruct.birchfield.common.states import BORDER, INVALID
from armstereo.reconstruct.birchfield.window.lanes import (
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

_RUN3 = np.ones((1, 3), np.uint8)  # the 3-pixel window of the variation flags


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


def variation_map(img: np.ndarray, lo: np.ndarray, hi: np.ndarray, forward: bool,
            out: np.ndarray | None = None) -> np.ndarray:
    """``out`` (H, W) uint8 (new if None), returned: 1 where the 3-pixel window at the pixel
    (``[x, x + 2]`` forward, ``[x - 2, x]`` backward, cut at the row's segment ``[lo, hi)``)
    varies by >= VARIATION_THRESHOLD, else 0. Only pixels inside the segment are
    meaningful."""
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
    # max and min of the 3 pixels from x on (anchor 0) or up to x (anchor 2), the row's last
    # (first) pixel repeated past its end: numpy's shifted copies took several times longer
    anchor = (0, 0) if forward else (2, 0)
    v = np.ascontiguousarray(v)
    mx = cv2.dilate(v, _RUN3, anchor=anchor, borderType=cv2.BORDER_REPLICATE)
    mn = cv2.erode(v, _RUN3, anchor=anchor, borderType=cv2.BORDER_REPLICATE)
    # mx - mn (uint8, mx >= mn: no wrap) >= VARIATION_THRESHOLD, as 1/0 straight into out
    if out is None:
        out = np.empty((H, W), np.uint8)
    cv2.threshold(cv2.subtract(mx, mn), VARIATION_THRESHOLD - 1, 1, cv2.THRESH_BINARY, dst=out)
    return out


def block_setup(left: np.ndarray, right: np.ndarray, lmask: np.ndarray, rmask: np.ndarray,
                textured: np.ndarray, dmin: int, nd: int, pens: np.ndarray, disp: np.ndarray,
                state: np.ndarray) -> tuple:
    """Set up every block of :data:`.lanes.LANES` rows of the (H, W) uint8 grey images.

    Resets ``disp`` (-1) and ``state`` (INVALID, BORDER on the left valid run) in place.
    Returns ``(geo, pen_l, rew, pen_r, ranges)``: per block ``b``, ``geo[b]`` (GEO, LANES)
    int64, ``pen_l[b]``/``rew[b]``/``pen_r[b]`` (W + nd + 2, LANES) float32 (``pen_r``'s
    columns from W on unused) as :func:`.lanes.lane_forward` and :func:`.lanes.lane_backtrack`
    read them, and
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
    disp.fill(-1)
    if (la == 0).all() and (lb == W).all():  # no rectification fill: every pixel on the run
        state.fill(BORDER)
    else:
        c = np.arange(W, dtype=np.int32)[None, :]
        inside = (c >= la.astype(np.int32)[:, None]) & (c < lb.astype(np.int32)[:, None])
        np.subtract(np.uint8(INVALID), inside.view(np.uint8) * np.uint8(INVALID - BORDER),
                    out=state)  # BORDER on the run

    # per-row bounds; an inactive row gets empty ranges (its values stay 0)
    n_u = W + nd + 2  # shifted left pixels u (image column u + dmin)
    edges = np.stack([np.where(active, v, empty) for v, empty in (
        (r0, n_u), (u1 + nd + 1, 0), (x0, n_u), (u1, 0), (r0, W), (r1, 0))]).astype(np.int32)
    occ, novar = pens[OCC], pens[NOVAR]
    values = np.array([occ, occ + novar, pens[REW], 0], np.float32)
    flags = np.empty((3, H, W), np.uint8)
    variation_map(left, la, lb, True, flags[0])
    np.copyto(flags[1], textured)
    variation_map(right, ra, rb, False, flags[2])
    lanes = np.empty((3, nb, n_u, LANES), np.float32)
    lanes[:, nb - 1, :, H - (nb - 1) * LANES:] = 0  # rows past H
    lane_penalties(edges, flags, dmin, values, lanes)
    pen_l, rew, pen_r = lanes  # pen_r's columns from W on are never read

    geo = np.zeros((nb * LANES, GEO), np.int64)
    for k, v in ((LA, la), (LB, lb), (R0, r0), (R1, r1), (X0, x0), (U1, u1), (RA, ra),
                 (RB, rb), (ACTIVE, active)):
        geo[:H, k] = np.where(active, v, 0)
    lo = np.full(nb * LANES, W, np.int64)  # rows past H: empty
    hi = np.zeros(nb * LANES, np.int64)
    lo[:H] = np.where(active, r0, W)
    hi[:H] = np.where(active, r1, 0)
    ranges = np.stack([lo.reshape(nb, LANES).min(axis=1), hi.reshape(nb, LANES).max(axis=1)],
                      axis=1)
    return (np.ascontiguousarray(geo.reshape(nb, LANES, GEO).transpose(0, 2, 1)),
            pen_l, rew, pen_r, ranges)


@njit(cache=True, nogil=True)
def lane_penalties(edges, flags, dmin, values, lanes):
    """Per-pixel penalties and rewards of every block, written in the lanes' layout.

    ``edges`` (6, H) int32: per row ``s0, s1`` (its span of shifted left pixels ``u``),
    ``e0, e1`` (where left occlusions may be cheap), ``r0, r1`` (its right pixels), all empty
    for an inactive row; ``flags`` (3, H, W) uint8 (0/1): intensity variation of the left image
    (forward), texture of the left image, variation of the right image (backward);
    ``values``: float32 ``[occ, occ + novar, reward, 0]``. Fills ``lanes[0, b, u, lane]``
    (pen_l: occ where ``e0 <= u < e1`` and the left pixel varies, else occ + novar, within
    ``[s0, s1)``), ``lanes[1]`` (rew: the reward where ``s0 <= u < e1`` and the left pixel is
    textured) and ``lanes[2, b, x, lane]`` (pen_r: occ or occ + novar by the right pixel's
    variation within ``[r0, r1)``), 0 elsewhere, for the H rows. The left pixel of ``u`` is
    image column ``u + dmin``, clamped to ``W - 1``, a negative one wrapping around as the
    kernels' indexing does (numba's wraparound). One pass, no whole-image temporaries:
    numpy's selects and transposes into this layout took ~2 ms of tsukuba's matcher
    (bench/results/dp_lanes.md); few arguments and one loop nest keep its compile short."""
    H, W = flags.shape[1], flags.shape[2]
    occ, occ_nv, reward, zero = values[0], values[1], values[2], values[3]  # in registers
    # lanes innermost: each (b, u) is 8 contiguous floats per output, and a block's 8 flag
    # rows stay in the L1 cache (by rows, every store missed it: 2x slower)
    for b in range(-(-H // LANES)):
        rows = min2(LANES, H - b * LANES)
        for u in range(lanes.shape[2]):
            c = u + dmin
            if c < 0:
                c += W
            c = min2(W - 1, max2(0, c))
            for lane in range(rows):
                r = b * LANES + lane
                pl = zero
                rw = zero
                pr = zero
                if edges[0, r] <= u < edges[1, r]:
                    pl = occ if edges[2, r] <= u < edges[3, r] and flags[0, r, c] else occ_nv
                    if u < edges[3, r] and flags[1, r, c]:
                        rw = reward
                if edges[4, r] <= u < edges[5, r]:
                    pr = occ if flags[2, r, u] else occ_nv
                lanes[0, b, u, lane] = pl
                lanes[1, b, u, lane] = rw
                lanes[2, b, u, lane] = pr
