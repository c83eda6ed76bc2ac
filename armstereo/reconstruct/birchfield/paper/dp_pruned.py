"""Birchfield-Tomasi scanline dynamic programme over match sequences (ICCV'98 "faster algorithm").

A search node ``(y, k)`` matches right pixel ``y`` with left pixel ``x = y + k``, ``0 <= k < nd``.
``phi(y, k)`` is the least cost of a match sequence ending with that match:

- start: ``phi(0, k) = C0 + d(k, 0)``: every sequence matches right pixel 0 first (left pixels
  before it are outside the right view and cost nothing);
- no occlusion ``(y, k) -> (y+1, k)``;
- left occlusion ``(y, k) -> (y+1, k2)``, ``k2 > k``: left pixels skipped, allowed at a left
  intensity variation at the new left pixel ``y + 1 + k2``;
- right occlusion ``(y, k) -> (y + k - k2 + 1, k2)``, ``k2 < k``: right pixels skipped, allowed
  at a right intensity variation at ``y``, the last matched right pixel;
- every step adds ``d(new match) - reward``; an occlusion adds ``occlusion`` once, whatever its
  length; an occlusion without the intensity variation adds :data:`NO_VARIATION_PENALTY` more;
- end: the cheapest node whose left pixel is the last one (ties: the largest ``k``).

With ``prune`` the occlusion steps are expanded only from nodes no dearer than the cheapest node
of their right pixel (left occlusions) or than the running minimum at their left pixel (right
occlusions), both with ``<=`` so ties expand: the reference code's pruning, a heuristic that can
miss the optimum. ``prune=False`` is the exact O(n nd^2) programme, the test oracle.
"""

from __future__ import annotations

import numpy as np

from armstereo.reconstruct.birchfield.common.cost import INF
from armstereo.reconstruct.birchfield.common.jit import njit
from armstereo.reconstruct.birchfield.common.states import C0, NO_VARIATION_PENALTY


@njit(cache=True, inline="always")
def _relax(phi, back, xmin, y, k, cost, pred):
    if cost < phi[y, k]:
        phi[y, k] = cost
        back[y, k] = pred
        if cost < xmin[y + k]:
            xmin[y + k] = cost


@njit(cache=True, inner=True)
def _expand_left(phi, back, xmin, dis, gl, y, k, c, occ, rew):
    """Left occlusions from node (y, k) into row y + 1 (disparity rises)."""
    nd = dis.shape[1]
    for k2 in range(k + 1, nd):
        d2 = dis[y + 1, k2]
        if d2 >= INF:  # left pixel past the end: so are all larger k2
            break
        p = occ if gl[y + 1 + k2] else occ + NO_VARIATION_PENALTY
        _relax(phi, back, xmin, y + 1, k2, c + p + d2 - rew, k)


@njit(cache=True, inner=True)
def _expand_right(phi, back, xmin, dis, gr, y, k, c, occ, rew):
    """Right occlusions from node (y, k): all land on left pixel y + k + 1 (disparity drops)."""
    ny = dis.shape[0]
    p = occ if gr[y] else occ + NO_VARIATION_PENALTY
    for k2 in range(k - 1, -1, -1):
        y2 = y + k - k2 + 1
        if y2 >= ny:
            break
        d2 = dis[y2, k2]
        if d2 < INF:
            _relax(phi, back, xmin, y2, k2, c + p + d2 - rew, k)


@njit(cache=True)
def scanline_dp(dis, gl, gr, occ, rew, prune, phi, back, match):
    """Best match sequence of one scanline; returns its cost (``INF`` if there is none).

    ``dis``: (ny, nd) int32 doubled dissimilarities, ``INF`` for impossible nodes;
    ``gl``/``gr``: left/right intensity-variation flags (length nx / ny); ``occ``/``rew``: doubled
    occlusion penalty and match reward. ``phi`` (int32) and ``back`` (int16) are (ny, nd) work
    arrays. Output ``match[x]`` = right pixel matched to left pixel ``x``, or -1.
    """
    ny, nd = dis.shape
    nx = gl.shape[0]
    match[:] = -1
    phi[:, :] = INF
    back[:, :] = -2
    xmin = np.full(nx + 1, INF, np.int32)
    for k in range(nd):
        if ny > 0 and dis[0, k] < INF:
            _relax(phi, back, xmin, 0, k, C0 + dis[0, k], -1)
    for y in range(ny):
        ymin = INF
        for k in range(nd):
            ymin = min(ymin, phi[y, k])
        if ymin >= INF:
            continue
        for k in range(nd):
            c = phi[y, k]
            if c >= INF:
                continue
            x = y + k
            if y + 1 < ny:
                dn = dis[y + 1, k]
                if dn < INF:
                    _relax(phi, back, xmin, y + 1, k, c + dn - rew, k)
                if not prune or c <= ymin:
                    _expand_left(phi, back, xmin, dis, gl, y, k, c, occ, rew)
            if x + 1 < nx and (not prune or c <= xmin[x]):
                _expand_right(phi, back, xmin, dis, gr, y, k, c, occ, rew)
    return _backtrack(phi, back, nx, match)


@njit(cache=True, inner=True)
def _backtrack(phi, back, nx, match):
    ny, nd = phi.shape
    best = INF
    by = -1
    bk = -1
    for k in range(nd):
        y = nx - 1 - k
        if 0 <= y < ny and phi[y, k] <= best and phi[y, k] < INF:
            best = phi[y, k]
            by = y
            bk = k
    if bk < 0:
        return INF
    y = by
    k = bk
    while True:
        match[y + k] = y
        pk = back[y, k]
        if pk == -1:
            break
        if pk <= k:
            y -= 1
        else:
            y = y + k - pk - 1
        k = pk
    return best

