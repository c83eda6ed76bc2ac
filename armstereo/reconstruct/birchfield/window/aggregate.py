"""The scanline programme on window-summed dissimilarities, plus one-pixel slant steps.

The paper matches each scanline on single-pixel dissimilarities, so neighbouring rows decide
independently (streaks) and every noise-level cost difference counts. Here the node cost of
``(right pixel xr, disparity index k)`` is the *sum* of the Birchfield-Tomasi dissimilarities
over a ``(2 ry + 1) x (2 rx + 1)`` window around it at the same disparity; the match-sequence
model, the occlusion rule (jumps only next to intensity variation) and the exact programme are
those of :mod:`..paper.dp_exact`, with the penalties scaled by the window's pixel count so that they
keep their per-pixel meaning. A one-pixel disparity step may also cost a smaller ``slant``
penalty, without intensity variation (a slanted surface rather than an occlusion).

Each row has its own programme, but rows run :data:`.lanes.LANES` at a time in lockstep, one
row per SIMD lane (:mod:`.lanes`): every step of the programme, the running minimum over
disparities included, is then one vector operation, and node costs are summed as the forward
pass goes. Every block's geometry and penalties are set up for the whole image at once
(:mod:`.blocks`), then a Python loop drives the blocks through two small kernels (forward,
backtrack), which numba compiles separately: far less compile time than one kernel with every
step inlined (bench/results/dp_lanes.md, coldstart.md). For windows one column wide (the
default 1x3 and the paper's 1x1) the forward kernel is :mod:`.fused`'s, which does a node's
cost and step in one loop of LLVM IR. Pixels outside the validity masks
take part in the sums with the edge-replicated values the caller fills in (a row's programme
itself only uses its valid run, as in :mod:`..common.scanline`).

The reward for a match can be withheld per left pixel (``textured``): matching a featureless
pixel then gains nothing, so the programme has no reason to bend its path through a black gap
at a wrong disparity and declare the textured pixels beside it occluded.

Costs are integer sums in float32, divided by ``q`` (floor) when a row could otherwise exceed
float32's exact integers: the programme's equality-based backtrack needs exact arithmetic.
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor

import cv2
import numpy as np

from armstereo.reconstruct.birchfield.common.cost import INF
from armstereo.reconstruct.birchfield.common.states import (
    BORDER,
    C0,
    EXACT_BELOW,
    MAX_PIXEL_COST,
    NO_VARIATION_PENALTY,
)
from armstereo.reconstruct.birchfield.window.blocks import block_setup
from armstereo.reconstruct.birchfield.window.fused import FUSED_MAX_RY, lane_forward_column
from armstereo.reconstruct.birchfield.window.lanes import (
    LANES,
    SLANT,
    image_bounds,
    lane_backtrack,
    lane_forward,
)
from armstereo.reconstruct.saturation import open_bounds

# rows cost unequal amounts: threads that take small chunks finish together, but a chunk's
# set-up costs 0.3-0.5 ms however small it is (bench/results/stereo_scaling.md)
CHUNKS_PER_THREAD = 4
MIN_CHUNK_BLOCKS = 12  # blocks of LANES rows (8, 12, 16 measured)


def cost_divisor(width: int, window_pixels: int, occ: int) -> int:
    """Smallest ``q`` keeping every path cost of a row exact in float32 (see the module doc)."""
    top = width * window_pixels * MAX_PIXEL_COST + 2 * (occ + NO_VARIATION_PENALTY) * (
        window_pixels) + C0
    return max(1, -(-top // (EXACT_BELOW // 2)))


def fill_outside(grey: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """Copy of an (H, W) image whose pixels left/right of each row's valid span repeat the
    span's edge pixels (so window sums near a mask edge see plausible values, not black)."""
    if mask.all():  # nothing outside (no rectification fill)
        return grey.copy()
    H, W = grey.shape
    has = mask.any(axis=1)
    a = np.where(has, np.argmax(mask, axis=1), 0)[:, None]
    b = np.where(has, W - 1 - np.argmax(mask[:, ::-1], axis=1), W - 1)[:, None]
    rows, cols = np.arange(H)[:, None], np.arange(W)
    # two selects rather than a gather of every pixel (take_along_axis): 3-4 ms -> 0.1 ms
    out = np.where(cols < a, grey[rows, a], grey)
    np.copyto(out, grey[rows, b], where=cols > b)
    return out


def match_image_aggregated(left: np.ndarray, right: np.ndarray, lmask: np.ndarray,
                           rmask: np.ndarray, dmin: int, nd: int, occ: int, rew: int, rx: int,
                           ry: int, *, slant: int = -1, textured: np.ndarray | None = None,
                           threads: int = 1, pool=None, keep_unmatched: bool = True,
                           saturated: tuple[np.ndarray, float] | None = None
                           ) -> dict[str, np.ndarray]:
    """Match (H, W) uint8 grey images on ``(2 ry + 1) x (2 rx + 1)`` aggregated costs.

    ``lmask``/``rmask``: (H, W) bool validity; the window is ``[dmin, dmin + nd - 1]``;
    ``occ``/``rew``/``slant``: doubled per-pixel occlusion penalty, match reward and
    one-pixel-jump penalty (-1: none); ``textured``: (H, W) bool, left pixels that earn the
    reward (None: all). Returns ``disp`` (H, W) int32 window indices (-1 = none) and ``state``
    (H, W) uint8 as :func:`armstereo.reconstruct.birchfield.paper.matcher.match_rows`. Blocks of
    :data:`.lanes.LANES` rows run on ``threads`` threads, each thread setting up and matching
    one chunk of blocks after another (:func:`block_strips`; up to CHUNKS_PER_THREAD per
    thread, each at least MIN_CHUNK_BLOCKS blocks):
    the calling thread and ``threads - 1`` of ``pool``'s (a ThreadPoolExecutor with that many
    workers; None: a pool of its own). ``keep_unmatched=False``: ``disp`` is -1 wherever
    ``state`` is BORDER or INVALID too (what a caller that does not fill them would do next,
    here chunk by chunk on the threads). ``saturated``: ``(codes, slack)`` of
    :func:`armstereo.reconstruct.saturation.saturation_codes` (left and right, (2, H, W)),
    whose pixels' intervals are opened (:func:`~armstereo.reconstruct.saturation.open_bounds`;
    None: none).
    """
    H, W = left.shape
    npix = (2 * rx + 1) * (2 * ry + 1)
    q = cost_divisor(W, npix, occ)
    out = dict(disp=np.empty((H, W), np.int32), state=np.empty((H, W), np.uint8))
    if textured is None:
        textured = np.ones((H, W), np.bool_)
    images = (left, right, lmask, rmask, np.asarray(textured, np.bool_), saturated)
    params = (dmin, nd, rx, ry, q, _scaled_penalties(occ, rew, slant, npix, q),
              keep_unmatched)
    threads = max(1, threads)
    per_thread = -(-H // LANES) // (threads * MIN_CHUNK_BLOCKS)  # whole chunks per thread
    chunks = block_strips(H, threads * max(1, min(CHUNKS_PER_THREAD, per_thread)))
    n = max(1, min(threads, len(chunks)))
    todo = iter(chunks)  # each thread takes the next chunk when it is done: rows differ in cost
    if n == 1:
        _match_chunks(todo, images, params, out)
    elif pool is None:
        with ThreadPoolExecutor(n - 1) as own:
            _on_threads(own, n, todo, images, params, out)
    else:
        _on_threads(pool, n, todo, images, params, out)
    return out


def _on_threads(pool, n: int, todo, images: tuple, params: tuple, out: dict) -> None:
    """:func:`_match_chunks` on the calling thread and ``n - 1`` of ``pool``'s."""
    jobs = [pool.submit(_match_chunks, todo, images, params, out) for _ in range(n - 1)]
    _match_chunks(todo, images, params, out)
    for job in jobs:
        job.result()


def block_strips(height: int, count: int) -> list[tuple[int, int]]:
    """Up to ``count`` strips ``(first, stop)`` of rows, each a run of whole blocks of
    :data:`.lanes.LANES` rows (the last one cut at ``height``), of about equal length."""
    nb = -(-height // LANES)
    n = max(1, min(nb, count))
    cuts = [round(i * nb / n) * LANES for i in range(n + 1)]
    return [(a, min(b, height)) for a, b in zip(cuts[:-1], cuts[1:], strict=True)]


def _match_chunks(todo, images: tuple, params: tuple, out: dict) -> None:
    """Set up and match chunks of rows ``(first, stop)`` (whole blocks) taken from the shared
    iterator ``todo`` until none is left: every step reads the images' rows it needs (the
    window's ``ry`` more each side) and writes only the chunk's rows of ``out``, so chunks
    can run side by side and give the maps of one pass over the image."""
    left, right, lmask, rmask, textured, saturated = images
    dmin, nd, rx, ry, q, pens, keep_unmatched = params
    work = _lane_work(left.shape[1], nd, rx, ry)
    for first, stop in todo:  # a list iterator: its next() is atomic under the GIL
        rows = slice(first, stop)
        mine = dict(disp=out["disp"][rows], state=out["state"][rows])  # block row 0 = first
        nj = (-(-(stop - first) // LANES) - 1) * LANES + _vector_rows(ry)
        bounds = np.empty((6, left.shape[1], nj), np.float32)
        image_bounds(*(_rows_transposed(img, mask, ry, first, stop, nj)
                       for img, mask in ((left, lmask), (right, rmask))), bounds)
        if saturated is not None:
            open_bounds(bounds, tuple(_rows_transposed(c, None, ry, first, stop, nj)
                                      for c in saturated[0]), saturated[1])
        setup = block_setup(left[rows], right[rows], lmask[rows], rmask[rows], textured[rows],
                            dmin, nd, pens, mine["disp"], mine["state"])
        _match_blocks(range(len(setup[4])), bounds, setup, params, mine, work)
        if not keep_unmatched:
            np.copyto(mine["disp"], -1, where=mine["state"] >= BORDER)


def _rows_transposed(grey: np.ndarray, mask: np.ndarray | None, ry: int, first: int, stop: int,
                     nj: int) -> np.ndarray:
    """(W, nj) uint8: the (H, W) image filled outside ``mask`` (:func:`fill_outside`; None:
    not filled), its row ``first + j - ry`` (clamped to the image) as column ``j``, as
    :func:`.lanes.image_bounds` reads it for the rows ``first .. stop - 1``. The clamped rows
    by one border copy (no gather, no fill when every pixel is valid)."""
    H = grey.shape[0]
    a, b = max(0, first - ry), min(H, stop + ry)  # the image rows the window reaches
    part = grey[a:b]
    valid = None if mask is None else mask[a:b]
    filled = (np.ascontiguousarray(part) if valid is None or valid.all()
              else fill_outside(part, valid))
    top = ry - (first - a)  # rows clamped to the image's first row
    return cv2.transpose(cv2.copyMakeBorder(filled, top, nj - (b - a) - top, 0, 0,
                                            cv2.BORDER_REPLICATE))


def _scaled_penalties(occ: int, rew: int, slant: int, npix: int, q: int) -> np.ndarray:
    """Per-pixel penalties and reward scaled to the window's pixel count and divided by
    ``q`` (rounded): float32 ``[occlusion, reward, no-variation, slant (INF: none)]``."""
    def scaled(v):
        return np.floor(v * npix / q + 0.5)
    return np.array([scaled(occ), scaled(rew), scaled(NO_VARIATION_PENALTY),
                     scaled(slant) if slant >= 0 else INF], np.float32)


def _match_blocks(blocks: range, bounds: np.ndarray, setup: tuple, params: tuple,
                  out: dict, work: tuple) -> None:
    """Match the blocks of rows ``blocks`` (indices; the kernels release the GIL), set up by
    :func:`.blocks.block_setup` (``setup``), with the thread's work arrays ``work``
    (:func:`_lane_work`)."""
    dmin, nd, rx, ry, q, pens, _ = params
    disp, state = out["disp"], out["state"]
    geos, pen_ls, rews, pen_rs, ranges = setup
    col_lims_ring_d, phi, rbest, run, ints, sloc = work
    costs = (bounds, *col_lims_ring_d)
    slant = pens[SLANT]
    fused = rx == 0 and 0 <= ry <= FUSED_MAX_RY and dmin >= 0  # the common windows
    for b in blocks:
        x_begin, x_end = int(ranges[b, 0]), int(ranges[b, 1])
        if x_end <= x_begin:
            continue
        row0, geo, pen_l, rew, pen_r = b * LANES, geos[b], pen_ls[b], rews[b], pen_rs[b]
        if fused:
            lane_forward_column(row0, ry, dmin, q, geo, x_begin, x_end, pen_l, rew, pen_r,
                                slant, costs, phi, rbest, run)
        else:
            lane_forward(row0, rx, ry, dmin, q, geo, x_begin, x_end, pen_l, rew, pen_r, slant,
                         costs, phi, rbest, run)
        lane_backtrack(geo, phi, costs[4], pen_l, rew, pen_r, slant, dmin, row0, ints, sloc,
                       disp, state)


def _vector_rows(ry: int) -> int:
    """Rows of a block and its window, in whole vectors of :data:`.lanes.LANES`."""
    return -(-(LANES + 2 * ry) // LANES) * LANES


def _lane_work(W: int, nd: int, rx: int, ry: int) -> tuple:
    """Work arrays of one thread for images ``W`` wide, allocated here rather than in the
    kernels: every array type a kernel creates compiles its own allocation code (numba's cold
    start).

    ``((col, lims, ring, d), phi, rbest, run, ints, sloc)`` as the kernels of :mod:`.lanes`
    name them (their ``costs`` is ``(bounds, col, lims, ring, d)``); ``phi`` starts INF (its
    padding stays so).
    """
    f32, L = np.float32, LANES
    costs = (np.empty((nd, _vector_rows(ry)), f32), np.empty((2, L), f32),
             np.empty((2 * rx + 1, nd, L), f32), np.empty((W, nd, L), f32))
    return (costs, np.full((W + 1, nd + 2, L), INF, f32), np.empty((W + nd + 1, L), f32),
            np.empty(L, f32), np.empty((2, W + nd), np.int32), np.empty(W + nd, np.uint8))
