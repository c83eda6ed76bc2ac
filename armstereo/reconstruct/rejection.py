"""From the programme's window indices to a map with NaN wherever a match is not trusted.

:func:`masked_map` turns the indices into a float32 map in one pass over strips of rows (the
fast sub-pixel step, the 5x5 median, NaN on unmatched pixels), then sets NaN on flat pixels
their textured surroundings do not confirm (:func:`unsupported`) and on pixels a nearer one
hides (:func:`hidden_by_nearer`), both by the kernel :func:`.birchfield.refine.row_rejects`.
After the other steps of the matcher: :func:`photo_inconsistent` (matches that do not look
alike near a depth jump) and :func:`reject_invalid_partners` (a right partner outside the
right image or its validity mask, for both matchers).
"""

from __future__ import annotations

import cv2
import numpy as np

from armstereo.reconstruct.birchfield.refine import row_rejects
from armstereo.reconstruct.plain import fill_plain
from armstereo.reconstruct.stereo_inputs import TEXTURE_WINDOW
from armstereo.reconstruct.strips import each_strip, row_strips
from armstereo.reconstruct.subpixel import SUBPIXEL_WINDOW, gradient_step

MEDIAN_SIZE = 5
FLAT_TOLERANCE = 1.0  # pixels: see unsupported
FLAT_SLOPE = 0.1  # disparity change per pixel a flat run may bridge
PHOTO_WINDOW = 3  # pixels: side of the photo-consistency check's window
PHOTO_EDGE_REACH = 16  # pixels along the row: how far from a depth jump fattening reaches
PHOTO_EDGE_JUMP = 2.0  # pixels of disparity: a jump a foreground can be carried across


def masked_map(pool, strips, gl, gr, idx, dmin, *, fast, median, flat, columns, hidden,
               plain=None):
    """The map in window units with every rejection before the left-right check: sub-pixel
    step, median, NaN on unmatched pixels, on flat pixels their surroundings do not confirm
    (:func:`unsupported`) and on pixels a nearer one hides (:func:`hidden_by_nearer`, with
    the margin ``hidden``; None = not tested), then the plain runs filled from their textured
    ends (:func:`.plain.fill_plain`, ``plain`` = its support; None = not filled). ``gl``/``gr``:
    the images the sub-pixel step fits. Returns ``(masked, reject)``: float32 (NaN where
    rejected) and the bool rejections."""
    masked = np.empty(idx.shape, np.float32)
    reject = np.empty(idx.shape, np.bool_)
    each_strip(pool, strips, _first_pass, gl, gr, idx, dmin, fast, median, masked, reject)
    fill = plain is not None and flat is not None
    before = masked.copy() if fill else None
    if flat is not None or hidden is not None:
        _flat_and_hidden(masked, reject, flat, FLAT_TOLERANCE, columns, hidden, apply=True,
                         pool=pool, strips=strips)
    if fill:
        fill_plain(masked, before, flat, tolerance=FLAT_TOLERANCE, slope=FLAT_SLOPE,
                   support=plain, pool=pool, strips=strips)
        np.logical_and(reject, np.isnan(masked), out=reject)  # filled: no longer rejected
    return masked, reject


def _first_pass(first, stop, gl, gr, idx, dmin, fast, median, masked, reject):
    """Rows ``first .. stop - 1`` of :func:`masked_map` up to the test of the flat pixels:
    the windows of the sub-pixel step and the median reach beyond the strip, so they run on
    a few rows more."""
    H = idx.shape[0]
    halo = (SUBPIXEL_WINDOW // 2 if fast else 0) + (MEDIAN_SIZE // 2 if median else 0)
    a, b = max(0, first - halo), min(H, stop + halo)
    part = idx[a:b]
    dense = part.astype(np.float32)  # the matching has set -1 on every pixel it rejects
    if fast:
        dense += gradient_step(gl[a:b], gr[a:b], part, dmin)
    rows, rej = masked[first:stop], reject[first:stop]
    np.less(idx[first:stop], 0, out=rej)
    if median and (a, b) == (first, stop):  # the whole image: straight into the map
        _median(dense, rows)
    else:
        if median:
            dense = _median(dense)
        np.copyto(rows, dense[first - a:stop - a])
    np.copyto(rows, np.float32(np.nan), where=rej)  # NaN where rejected so far


def add_rejections(masked: np.ndarray, reject: np.ndarray, new: np.ndarray) -> None:
    """Add ``new`` to the (H, W) bool ``reject`` and set NaN there in ``masked`` (in place)."""
    reject |= new
    masked[new] = np.nan


def _median(dense: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
    """MEDIAN_SIZE median of the float32 map (into ``out`` if given, same shape). Unmatched
    pixels (-1) take part like the others; the caller sets them NaN afterwards."""
    return cv2.medianBlur(dense, MEDIAN_SIZE, dst=out)


def hidden_by_nearer(disp: np.ndarray, margin: float) -> np.ndarray:
    """Left pixels that a nearer pixel of the same map hides in the right view.

    ``x - d(x)`` is the pixel's right-image position; it is hidden when that lies at least
    ``margin`` pixels right of the leftmost right-image position of the pixels to its right
    (``margin = 1`` tolerates the one-pixel ties of slanted surfaces). NaN takes no part
    (and is not marked). The map itself is not changed.
    """
    hidden = np.zeros(disp.shape, np.bool_)
    _flat_and_hidden(np.array(disp, np.float32), hidden, None, 0.0, False, margin, apply=False)
    return hidden


def unsupported(disp: np.ndarray, flat: np.ndarray, tolerance: float,
                columns: bool = False) -> np.ndarray:
    """Flat pixels whose disparity their row's textured surroundings do not confirm.

    A flat pixel is kept only when the nearest textured pixels with a disparity to its left
    and to its right on the same row both exist, differ by at most ``tolerance`` plus
    FLAT_SLOPE per pixel between them, and its disparity lies between theirs (+-
    ``tolerance``): a plain wall between two edges of the same surface, not a gap or a
    background that the programme had to invent a disparity for. A run of flat pixels with
    a disparity next to a break (no disparity, or the image's edge) within two texture
    windows needs only the anchor at its other end. With ``columns``, a flat pixel its row
    rejects is still kept when the same test along its column (above and below it) confirms
    it. ``disp``: (H, W) disparities (NaN = none); ``flat``: (H, W) bool; ``tolerance`` >= 0
    pixels. Returns the (H, W) bool pixels rejected.
    """
    disp = np.ascontiguousarray(disp, np.float32)
    return _flat_and_hidden(disp, np.empty(disp.shape, np.bool_), flat, tolerance, columns,
                            None, apply=False)


def _flat_and_hidden(disp: np.ndarray, reject: np.ndarray, flat: np.ndarray | None,
                     tolerance: float, columns: bool, hidden: float | None, *, apply: bool,
                     pool=None, strips: list[tuple[int, int]] | None = None) -> np.ndarray:
    """:func:`unsupported` of the (H, W) float32 ``disp`` (None ``flat``: not tested), with
    ``apply`` set to NaN in ``disp`` and True in ``reject`` there, then the pixels
    :func:`hidden_by_nearer` finds with the margin ``hidden`` (None: not tested) likewise
    (in place, :func:`row_rejects`). Returns the unsupported pixels. ``strips`` of rows run
    side by side on ``pool`` (the column test first, on as many strips of columns)."""
    H, W = disp.shape
    strips = strips or [(0, H)]
    out = np.empty((H, W), np.bool_)
    kind = along = None
    if flat is not None:
        kind = np.empty((H, W), np.uint8)  # 2 * flat + finite (KIND_*)
        each_strip(pool, strips, _kinds, disp, np.ascontiguousarray(flat, np.bool_), kind)
        if columns:  # the same test along the columns, on strips of columns
            along = np.empty((H, W), np.bool_)
            each_strip(pool, row_strips(W, len(strips)), _columns, disp, kind, tolerance, along)
    each_strip(pool, strips, _rows, disp, kind, along, reject, tolerance, hidden, apply, out)
    return out


def _kinds(first: int, stop: int, disp: np.ndarray, flat: np.ndarray, kind: np.ndarray) -> None:
    """Rows ``first .. stop - 1`` of ``kind``: 2 * flat + answered (the KIND_* of
    :func:`row_rejects`)."""
    rows = kind[first:stop]
    np.isfinite(disp[first:stop], out=rows.view(np.bool_))
    rows += flat[first:stop].view(np.uint8) * np.uint8(2)


def _columns(first: int, stop: int, disp: np.ndarray, kind: np.ndarray, tolerance: float,
             along: np.ndarray) -> None:
    """Columns ``first .. stop - 1`` of the column test (``along``): the row test of
    :func:`_rows` on transposed copies (OpenCV's transpose: several times faster than
    numpy's copy of a transposed view)."""
    across = np.empty((stop - first, disp.shape[0]), np.bool_)
    _rows(0, stop - first, cv2.transpose(disp[:, first:stop]),
          cv2.transpose(kind[:, first:stop]), None, across, tolerance, None, False, across)
    along[:, first:stop] = cv2.transpose(across.view(np.uint8)).view(np.bool_)


def _rows(first: int, stop: int, disp: np.ndarray, kind: np.ndarray | None,
          along: np.ndarray | None, reject: np.ndarray, tolerance: float, hidden: float | None,
          apply: bool, out: np.ndarray) -> None:
    """Rows ``first .. stop - 1`` of :func:`_flat_and_hidden` (:func:`row_rejects`; None
    arrays: not used)."""
    no_kind = np.empty((0, 0), np.uint8)  # read only with kind
    row_rejects(disp, no_kind if kind is None else kind, out if along is None else along, reject,
                disp, np.float64(tolerance), np.float64(FLAT_SLOPE),
                np.int64(2 * TEXTURE_WINDOW), np.float64(0.0 if hidden is None else hidden),
                np.float64(0.0), np.bool_(kind is not None), np.bool_(along is not None),
                np.bool_(apply), np.bool_(hidden is not None), np.bool_(False),
                np.int64(first), np.int64(stop), out)


def photo_inconsistent(left: np.ndarray, right: np.ndarray, disp: np.ndarray,
                       threshold: float) -> np.ndarray:
    """Left pixels whose match does not look alike: the mean absolute grey difference
    ``|L(x) - R(x - d(x))|`` (right image linearly interpolated), each pixel at its own
    disparity, averaged over the PHOTO_WINDOW square of answered pixels, exceeds
    ``threshold`` grey levels, within PHOTO_EDGE_REACH px along the row of a depth jump.
    ``left``/``right``: (H, W) uint8 grey; ``disp``: float32 disparities (NaN = none)."""
    H, W = disp.shape
    ok = np.isfinite(disp)
    xr = np.arange(W, dtype=np.float32)[None, :] - np.where(ok, disp, np.float32(0))
    yr = np.broadcast_to(np.arange(H, dtype=np.float32)[:, None], (H, W))
    warped = cv2.remap(right.astype(np.float32), xr, np.ascontiguousarray(yr),
                       cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
    err = np.where(ok, np.abs(left.astype(np.float32) - warped), np.float32(0))
    win = (PHOTO_WINDOW, PHOTO_WINDOW)
    total = cv2.boxFilter(err, -1, win, normalize=False)
    count = cv2.boxFilter(ok.astype(np.float32), -1, win, normalize=False)
    return ok & (total > np.float32(threshold) * count) & _near_depth_jump(disp)


def _near_depth_jump(disp: np.ndarray) -> np.ndarray:
    """Pixels within PHOTO_EDGE_REACH px along their row of a disparity differing from
    theirs by more than PHOTO_EDGE_JUMP: where a foreground can be carried across its edge.
    Elsewhere a large residual is steep texture or noise, not fattening."""
    kernel = np.ones((1, 2 * PHOTO_EDGE_REACH + 1), np.uint8)
    ok = np.isfinite(disp)
    hi = cv2.dilate(np.where(ok, disp, np.float32(-np.inf)).astype(np.float32), kernel)
    lo = cv2.erode(np.where(ok, disp, np.float32(np.inf)).astype(np.float32), kernel)
    with np.errstate(invalid="ignore"):
        return (hi - disp > PHOTO_EDGE_JUMP) | (disp - lo > PHOTO_EDGE_JUMP)


def clip_to_window(disp: np.ndarray, min_disparity: int, max_disparity: int) -> np.ndarray:
    """Sub-pixel steps may leave the searched window by a fraction: clamp them back (in
    place; returns ``disp``)."""
    np.clip(disp, min_disparity, min_disparity + max_disparity, out=disp)
    return disp


def reject_invalid_partners(disp: np.ndarray, rmask: np.ndarray,
                            largest: float | None = None) -> None:
    """NaN where the matched right pixel ``x - d`` (nearest pixel) is outside the right image
    or its validity mask (in place). ``largest``: no disparity exceeds it (None: unknown)."""
    H, W = disp.shape
    if rmask.all():  # only the left edge can be crossed (d >= 0); NaN compares False
        # x - d < -1/2 needs x < d: only the columns left of the largest disparity
        band = disp if largest is None else disp[:, :max(0, min(W, int(np.ceil(largest))))]
        with np.errstate(invalid="ignore"):
            band[np.rint(np.arange(band.shape[1], dtype=np.float32) - band) < 0] = np.nan
        return
    # x - d in float64 (exact), rounded; NaN stays NaN and compares False
    xr = np.subtract(np.arange(W, dtype=np.float64), disp)
    np.rint(xr, out=xr)
    runs = single_runs(rmask)
    with np.errstate(invalid="ignore"):
        if runs is not None:  # a rectification's mask: one run [a, b) of valid pixels per row
            # float64 bounds: compared with int columns, numpy would convert every pixel's
            # float to float64 on the way; converting the H bounds once is cheaper
            a, b = (r.astype(np.float64) for r in runs)
            ok = xr >= a
            ok &= xr < b
        else:
            ok = xr >= 0
            ok &= xr < W
            np.copyto(xr, 0, where=~ok)
            at = xr.astype(np.intp)
            at += np.arange(0, H * W, W, dtype=np.intp)[:, None]  # flat index of the partner
            ok &= rmask.ravel().take(at)
    bad = np.isfinite(disp)
    bad &= ~ok
    disp[bad] = np.nan


def single_runs(mask: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """``(a, b)``, (H, 1) int columns, when each row's True pixels are the one run
    ``a <= x < b`` (``a = W, b = 0`` on an empty row); None if some row has more runs."""
    H, W = mask.shape
    count = np.count_nonzero(mask, axis=1)
    a = np.argmax(mask, axis=1)
    b = W - np.argmax(mask[:, ::-1], axis=1)
    if not np.all((count == b - a) | (count == 0)):
        return None
    return np.where(count > 0, a, W)[:, None], np.where(count > 0, b, 0)[:, None]
