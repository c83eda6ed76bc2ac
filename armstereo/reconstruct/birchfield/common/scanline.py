"""One image row: its valid runs, the part of it the programme can match, its decoding.

Shared by every route (:mod:`..paper.matcher`, :mod:`..window.lanes`, :mod:`..columns.vertical`):
row ``r`` is matched on the longest run of valid pixels of each image; with the window
``[dmin, dmin + nd - 1]`` the left pixel ``xL`` is indexed by ``u = xL - dmin`` so that the
programme sees disparity indices ``k = u - xR`` in ``[0, nd)`` (:func:`row_geometry`).
:func:`begin_row` resets a row's outputs, :func:`store_row` decodes its match sequence
(:func:`decode_matches`, the reference code's policy) into the image row. The default
matcher's backtrack (:func:`..window.lanes.lane_backtrack`) decodes by the same policy while
it walks, without a match sequence.
"""

from __future__ import annotations

from armstereo.reconstruct.birchfield.common.jit import njit
from armstereo.reconstruct.birchfield.common.minmax import max2, min2
from armstereo.reconstruct.birchfield.common.states import BORDER, INVALID, MATCHED, OCCLUDED


@njit(cache=True, inline="always")
def longest_run(valid):
    """``(start, stop)`` of the longest run of True in ``valid`` (``(0, 0)`` if none)."""
    best_a = 0
    best_b = 0
    a = -1
    n = valid.shape[0]
    for i in range(n + 1):
        if i < n and valid[i]:
            if a < 0:
                a = i
        elif a >= 0:
            if i - a > best_b - best_a:
                best_a = a
                best_b = i
            a = -1
    return best_a, best_b


@njit(cache=True, inline="always")
def row_geometry(la, lb, ra, rb, dmin, nd):
    """Right pixels ``[r0, r1)`` and shifted left pixels ``[x0, u1)`` that can take part.

    Left pixel ``u`` (= xL - dmin) can match right pixels ``u - nd + 1 .. u`` only.
    """
    u0 = la - dmin
    u1 = min2(lb - dmin, rb + nd - 1)
    r0 = max2(ra, u0 - nd + 1)
    r1 = min2(rb, u1)
    x0 = max2(u0, r0)
    return r0, r1, x0, u1


@njit(cache=True, inner=True)
def begin_row(lmask_row, rmask_row, dmin, nd, disp_row, state_row):
    """Reset one row's outputs; returns ``(la, lb, r0, r1, x0, u1, ra, rb)``: the valid runs
    and the geometry of :func:`row_geometry`."""
    # plain loops: numba compiles a slice assignment into far more code (cold start)
    for x in range(disp_row.shape[0]):
        disp_row[x] = -1
        state_row[x] = INVALID
    la, lb = longest_run(lmask_row)
    ra, rb = longest_run(rmask_row)
    for x in range(la, lb):
        state_row[x] = BORDER
    r0, r1, x0, u1 = row_geometry(la, lb, ra, rb, dmin, nd)
    return la, lb, r0, r1, x0, u1, ra, rb


@njit(cache=True, inner=True)
def store_row(match, la, lb, r0, x_lo, dmin, dloc, sloc, disp_row, state_row):
    """Decode one row's match sequence (local coordinates) into the image row."""
    nx = match.shape[0]
    decode_matches(match, dloc[:nx], sloc[:nx])
    off = r0 + dmin  # image column of local left pixel 0
    for x in range(x_lo, nx):
        disp_row[off + x] = dloc[x]
        state_row[off + x] = sloc[x]
    # valid left pixels that cannot be matched keep BORDER and take the nearest decoded
    # disparity (the reference code's dense border policy)
    for x in range(la, min2(off + x_lo, disp_row.shape[0])):
        disp_row[x] = dloc[x_lo]
    for x in range(off + nx, min2(lb, disp_row.shape[0])):
        disp_row[x] = dloc[nx - 1]


@njit(cache=True, inline="always")
def decode_matches(match, disp, state):
    """Per-left-pixel disparity index and state from ``match`` (reference-code decoding).

    Matched pixels get their ``k``; left-occluded runs get the smaller (background) ``k`` of the
    match before them; pixels before the first match get its ``k`` and state BORDER.
    """
    nx = match.shape[0]
    first = -1
    last_k = -1
    for x in range(nx):
        if match[x] >= 0:
            last_k = x - match[x]
            disp[x] = last_k
            state[x] = MATCHED
            if first < 0:
                first = x
        else:
            disp[x] = last_k
            state[x] = OCCLUDED if first >= 0 else BORDER
    if first < 0:
        for x in range(nx):
            disp[x] = -1
            state[x] = BORDER
        return
    for x in range(first):
        disp[x] = first - match[first]
    # trailing unmatched pixels cannot occur (the last left pixel is always matched) unless the
    # caller cropped the row; treat them as border
    for x in range(nx - 1, -1, -1):
        if match[x] >= 0:
            break
        state[x] = BORDER
