"""Flat objects: sheets lying on the support plane (paper, a notepad, a mat, a thin book).

A sheet a millimetre or two thick never enters the object band (``plane_threshold_m`` above
the plane, set by the table's per-point noise), so the clustering cannot see it. What does see
it is the median height of a table cell: on the realistic desk a 2 cm cell's median scatters
by about +-1 mm on bare table, far less than a single point's 4-5 mm, while the cells of the
desk's 2 mm notes pad stand 1-2.5 mm above the plane fitted through everything (seeds 0-9,
both matchers, bench/results/cell.md).

:func:`flat_regions` marks the cells whose median height lies between ``height_m`` and the
object band, away (``margin_m``) from cells that stand in the band (an object, the mismatches
beside it, its shadow's fringe), and keeps the connected groups of at least ``min_area_m2``.
The area is what tells a sheet from the table's own noise: scattered cells and streaks of the
matcher's errors made groups of at most 52 cm^2 at 0.3-0.5 mm on those clouds, the notes pad
(280 cm^2) made one of 100-350 cm^2. A sheet raises the plane's cell refit by a share of its
height (a quarter of the table's free cells on the desk), so :func:`.analysis.analyze_scene`
refits the plane without the regions found and looks again about the refit plane.

Coordinates are the plane frame's (u, v, h), metres.
"""

from __future__ import annotations

import cv2
import numpy as np

CELL_MIN_POINTS = 10  # a cell's median counts with at least this many points
# at most about this many points give the cells' medians (a fixed stride): a 2 cm cell of the
# realistic desk's cloud holds ~250 points, 60 of them give its median to well under the
# table's correlated error, and sorting every point doubled the plane step's time
CELL_SAMPLE = 60_000


def cell_medians(uvh: np.ndarray, cell_m: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(medians (R, C) m of the heights of ``uvh`` (N, 3) binned into ``cell_m`` squares of
    the plane, from a fixed-stride subset of about CELL_SAMPLE points, NaN where a cell
    holds fewer than CELL_MIN_POINTS of them; the flat cell index of every point (N,); the
    grid's shape)."""
    ij = np.floor(uvh[:, :2] / cell_m).astype(np.int64)
    ij -= ij.min(axis=0)
    shape = (int(ij[:, 0].max()) + 1, int(ij[:, 1].max()) + 1)
    flat = ij[:, 0] * shape[1] + ij[:, 1]
    step = max(1, len(uvh) // CELL_SAMPLE)
    h, cells = uvh[::step, 2], flat[::step]
    order = np.lexsort((h, cells))
    fs = cells[order]
    starts = np.flatnonzero(np.r_[True, fs[1:] != fs[:-1]])
    counts = np.diff(np.r_[starts, len(fs)])
    med = np.full(shape[0] * shape[1], np.nan)
    ok = counts >= CELL_MIN_POINTS
    med[fs[starts[ok]]] = h[order[starts[ok] + counts[ok] // 2]]
    return med.reshape(shape), flat, np.array(shape)


def flat_regions(uvh: np.ndarray, *, cell_m: float, height_m: float, band_m: float,
                 margin_m: float, min_area_m2: float) -> list[np.ndarray]:
    """Point indices (into ``uvh``, (N, 3) plane coordinates, m) of each flat region (module
    doc): connected ``cell_m`` cells (8-neighbours) with median heights in ``[height_m,
    band_m)``, none within ``margin_m`` of a cell whose median reaches ``band_m``, the group
    covering at least ``min_area_m2``. Largest first."""
    if len(uvh) == 0:
        return []
    med, flat, _ = cell_medians(uvh, cell_m)
    known = np.isfinite(med)
    h = np.where(known, med, 0.0)
    standing = (known & (h >= band_m)).astype(np.uint8)
    r = int(np.ceil(margin_m / cell_m - 1e-9))
    if r > 0:
        standing = cv2.dilate(standing, cv2.getStructuringElement(cv2.MORPH_ELLIPSE,
                                                                  (2 * r + 1,) * 2))
    candidate = (known & (h >= height_m) & (h < band_m) & (standing == 0)).astype(np.uint8)
    n, labels, stats, _ = cv2.connectedComponentsWithStats(candidate, connectivity=8)
    min_cells = min_area_m2 / (cell_m * cell_m)
    big = [k for k in range(1, n) if stats[k, cv2.CC_STAT_AREA] >= min_cells - 1e-9]
    big.sort(key=lambda k: -stats[k, cv2.CC_STAT_AREA])
    of_point = labels.reshape(-1)[flat]
    return [np.flatnonzero(of_point == k) for k in big]
