"""Objects as connected groups of points: a voxel connected-components pass.

Points are binned into cubic voxels of edge ``voxel_m``; voxels holding at least
``min_voxel_points`` points are *dense* (the voxel analogue of DBSCAN's core points); dense
voxels are joined to their 26 neighbours and split into connected components
(``scipy.sparse.csgraph``); a sparse voxel next to a dense one joins its component (DBSCAN's
border points), a sparse voxel with no dense neighbour is noise. Two points end up in one
cluster when a chain of occupied voxels links them, i.e. when the gaps between them are
below one to two voxel edges: the same single-linkage idea as DBSCAN with ``eps`` ~
``voxel_m`` and PCL's Euclidean cluster extraction, at a fraction of the cost
(``bench/scene.py`` compares it with scikit-learn's DBSCAN on the same points). Voxels are
sparse (sorted integer keys), so far outliers cost nothing.
"""

from __future__ import annotations

import cv2
import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

NOISE = -1
_KEY_BITS = 21  # per axis: +-1M voxels (5 km at 5 mm)
_OFFSET = 1 << (_KEY_BITS - 1)
# the 13 "forward" neighbours of a voxel; with their mirror images they make all 26
_FORWARD = np.array([(dx, dy, dz) for dx in (-1, 0, 1) for dy in (-1, 0, 1) for dz in (-1, 0, 1)
                     if (dx, dy, dz) > (0, 0, 0)], dtype=np.int64)


def voxel_clusters(points: np.ndarray, voxel_m: float, *, min_voxel_points: int = 2,
                   min_cluster_points: int = 1) -> np.ndarray:
    """Cluster label (N,) for each point (N, 3, metres, any frame): 0, 1, ... by decreasing
    size, :data:`NOISE` for points in sparse voxels or in clusters smaller than
    ``min_cluster_points``."""
    pts = np.asarray(points, dtype=float)
    labels = np.full(len(pts), NOISE, dtype=np.int64)
    if len(pts) == 0:
        return labels
    if not voxel_m > 0:
        raise ValueError(f"voxel size must be positive, got {voxel_m}")
    ijk = np.floor((pts - pts.min(axis=0)) / voxel_m).astype(np.int64)
    if ijk.max() >= 2 * _OFFSET - 1:
        raise ValueError(f"cloud spans more than {2 * _OFFSET - 2} voxels of {voxel_m} m")
    keys, point_voxel, counts = np.unique(_pack(ijk), return_inverse=True, return_counts=True)
    dense = counts >= min_voxel_points
    keys_d = keys[dense]
    n = len(keys_d)
    if n == 0:
        return labels
    vox = _unpack(keys_d)
    rows, cols = [np.arange(n)], [np.arange(n)]
    for off in _FORWARD:
        nb = _pack(vox + off)
        pos = np.clip(np.searchsorted(keys_d, nb), 0, n - 1)
        hit = keys_d[pos] == nb
        rows.append(np.flatnonzero(hit))
        cols.append(pos[hit])
    r, c = np.concatenate(rows), np.concatenate(cols)
    graph = coo_matrix((np.ones(len(r), dtype=np.int8), (r, c)), shape=(n, n))
    _, comp = connected_components(graph, directed=False)
    voxel_label = np.full(len(keys), NOISE, dtype=np.int64)
    voxel_label[dense] = comp
    voxel_label[~dense] = _border_labels(_unpack(keys[~dense]), keys_d, comp)
    labels = voxel_label[point_voxel]
    return _relabel_by_size(labels, min_cluster_points)


def _border_labels(vox: np.ndarray, keys_d: np.ndarray, comp: np.ndarray) -> np.ndarray:
    """Label of a dense neighbour for each sparse voxel (NOISE if it has none): like
    DBSCAN's border points, a sparse voxel touching an object belongs to it."""
    out = np.full(len(vox), NOISE, dtype=np.int64)
    for off in np.vstack([_FORWARD, -_FORWARD]):
        nb = _pack(vox + off)
        pos = np.clip(np.searchsorted(keys_d, nb), 0, len(keys_d) - 1)
        hit = (keys_d[pos] == nb) & (out == NOISE)
        out[hit] = comp[pos[hit]]
    return out


def _pack(ijk: np.ndarray) -> np.ndarray:
    """One sortable int64 key per voxel (x major); coordinates offset to stay non-negative."""
    q = ijk + _OFFSET
    return (q[:, 0] << (2 * _KEY_BITS)) | (q[:, 1] << _KEY_BITS) | q[:, 2]


def _unpack(keys: np.ndarray) -> np.ndarray:
    mask = (1 << _KEY_BITS) - 1
    return np.stack([keys >> (2 * _KEY_BITS), (keys >> _KEY_BITS) & mask, keys & mask],
                    axis=1) - _OFFSET


def _relabel_by_size(labels: np.ndarray, min_points: int) -> np.ndarray:
    """Labels renumbered 0, 1, ... by decreasing cluster size; small clusters -> NOISE."""
    out = np.full(len(labels), NOISE, dtype=np.int64)
    valid = labels >= 0
    if not valid.any():
        return out
    ids, inverse, counts = np.unique(labels[valid], return_inverse=True, return_counts=True)
    order = np.argsort(-counts, kind="stable")
    rank = np.empty(len(ids), dtype=np.int64)
    rank[order] = np.arange(len(ids))
    new = rank[inverse]
    new[counts[inverse] < min_points] = NOISE
    out[valid] = new
    return out


def split_bridged(uv: np.ndarray, labels: np.ndarray, cell_m: float, neck_m: float,
                  min_area_m2: float) -> np.ndarray:
    """Labels (N,) with every cluster that is two objects joined by a narrow bridge split.

    A cluster's top view (``uv`` (N, 2) plane coordinates, m, rasterised in cells of
    ``cell_m``) is eroded by ``neck_m`` on every side; when two or more parts of at least
    ``min_area_m2`` (before erosion) survive, each point goes to the part nearest to it. The
    bridges this cuts are the strips of mismatches stereo leaves between close objects (a gap
    the matcher filled at object height, the image border's streaks): narrower than
    ``2 * neck_m``, they link objects in 3-D but vanish in an opening. A cluster that survives
    the erosion as one part (or not at all: a thin object) is left alone. New clusters get
    labels after the existing ones; :data:`NOISE` stays."""
    out = labels.copy()
    radius = max(1, int(round(neck_m / cell_m)))
    kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * radius + 1, 2 * radius + 1))
    next_label = int(labels.max()) + 1 if len(labels) else 0
    for k in range(next_label):
        idx = np.flatnonzero(labels == k)
        parts = _bridged_parts(uv[idx], cell_m, kernel, radius, min_area_m2)
        if parts is None:
            continue
        for p in range(1, int(parts.max()) + 1):
            out[idx[parts == p]] = next_label
            next_label += 1
    return out


def _bridged_parts(uv: np.ndarray, cell_m: float, kernel: np.ndarray, radius: int,
                   min_area_m2: float) -> np.ndarray | None:
    """Part index (N,) 0, 1, ... of each point, or None when the cluster is one part."""
    ij = np.floor((uv - uv.min(axis=0)) / cell_m).astype(np.int64) + radius + 1
    shape = (int(ij[:, 1].max()) + radius + 2, int(ij[:, 0].max()) + radius + 2)
    occupied = np.zeros(shape, dtype=np.uint8)
    occupied[ij[:, 1], ij[:, 0]] = 1
    occupied = cv2.morphologyEx(occupied, cv2.MORPH_CLOSE, np.ones((3, 3), np.uint8))
    core = cv2.erode(occupied, kernel)
    n, comp = cv2.connectedComponents(core, connectivity=8)
    if n <= 2:
        return None
    # each part's area before erosion: its core grown back, within the cluster's top view
    grown = [cv2.dilate((comp == c).astype(np.uint8), kernel) & occupied for c in range(1, n)]
    big = [c for c, g in zip(range(1, n), grown, strict=True)
           if g.sum() * cell_m ** 2 >= min_area_m2]
    if len(big) < 2:
        return None
    cell_part, _ = _nearest_part(comp, big)
    return cell_part[ij[:, 1], ij[:, 0]]


def _nearest_part(comp: np.ndarray, big: list[int]) -> tuple[np.ndarray, np.ndarray]:
    """For every cell of the component image ``comp`` (int labels), the index into ``big``
    of the nearest cell of one of those components, and the distance to it (cells): a
    distance transform with labels."""
    seeds = np.ones(comp.shape, dtype=np.uint8)
    for c in big:
        seeds[comp == c] = 0
    dist, nearest = cv2.distanceTransformWithLabels(seeds, cv2.DIST_L2, 5,
                                                    labelType=cv2.DIST_LABEL_PIXEL)
    seed_cells = np.flatnonzero(seeds.reshape(-1) == 0)
    seed_part = np.searchsorted(big, comp.reshape(-1)[seed_cells])
    # DIST_LABEL_PIXEL numbers the zero pixels 1.. in row-major order
    return seed_part[nearest - 1], dist


def split_valleys(uv: np.ndarray, high: np.ndarray, labels: np.ndarray, cell_m: float,
                  min_area_m2: float, reach_m: float) -> np.ndarray:
    """Labels (N,) with every cluster whose tops stand apart over a low valley split.

    ``uv`` (N, 2): plane coordinates, m; ``high`` (N,) bool: the point lies in a plane cell
    of ``cell_m`` (the grid ``floor(uv / cell_m)``) whose points, the table's too, have an
    object's median height. When a cluster's high cells fall into two or more parts of at
    least ``min_area_m2``, every point within ``reach_m`` of a part goes to the nearest part,
    the rest (the low valley far from every top: mismatches, a sheet too thin to be an
    object) to :data:`NOISE`. Two close objects whose gap the matcher filled with points a
    few millimetres high are joined in 3-D by that band however wide it is, and
    split_bridged cuts only narrow bridges. A cluster with one high part (one object with a
    low skirt) is left alone. New labels follow the existing ones."""
    out = labels.copy()
    next_label = int(labels.max()) + 1 if len(labels) else 0
    for k in range(next_label):
        idx = np.flatnonzero(labels == k)
        parts = _valley_parts(uv[idx], high[idx], cell_m, min_area_m2, reach_m)
        if parts is None:
            continue
        out[idx[parts < 0]] = NOISE
        for p in range(1, int(parts.max()) + 1):
            out[idx[parts == p]] = next_label
            next_label += 1
    return out


def _valley_parts(uv: np.ndarray, high: np.ndarray, cell_m: float, min_area_m2: float,
                  reach_m: float) -> np.ndarray | None:
    """Part index (N,) 0, 1, ... of each point (-1: beyond ``reach_m`` of every part), or None
    when the cluster has fewer than two high parts."""
    ij = np.floor(uv / cell_m).astype(np.int64)
    ij -= ij.min(axis=0) - 1
    shape = (int(ij[:, 1].max()) + 2, int(ij[:, 0].max()) + 2)
    cell = ij[:, 1] * shape[1] + ij[:, 0]
    top = np.zeros(shape[0] * shape[1], dtype=np.uint8)
    top[cell[high]] = 1
    n, comp = cv2.connectedComponents(top.reshape(shape), connectivity=8)
    if n <= 2:
        return None
    area = np.bincount(comp.reshape(-1), minlength=n)[1:] * cell_m ** 2
    big = [c for c in range(1, n) if area[c - 1] >= min_area_m2]
    if len(big) < 2:
        return None
    cell_part, dist = _nearest_part(comp, big)
    cell_part[dist * cell_m > reach_m] = -1
    return cell_part.reshape(-1)[cell]


def merge_covered(uvh: np.ndarray, labels: np.ndarray, cell_m: float, share: float,
                  tolerance_m: float, *, eligible: list[int] | None = None) -> np.ndarray:
    """Labels (N,) with every cluster that stands within a larger cluster's top view, no
    higher than it, merged into it.

    ``uvh`` (N, 3): plane coordinates and heights, m; top views rasterised in cells of
    ``cell_m``. A cluster at least ``share`` of whose cells hold points of a larger cluster
    too, and whose top (95th percentile height) is at most ``tolerance_m`` above that
    cluster's, takes its label (the smallest clusters first). Seen obliquely, an object's side
    and its top can be apart in 3-D by more than a voxel (the edge the matcher lost), yet they
    are one object; two objects side by side share only their boundary cells, and a
    mismatch blob floating above an object is higher than it. Only the clusters ``eligible``
    (None: all) merge or are merged; :data:`NOISE` stays."""
    out = labels.copy()
    n = int(labels.max()) + 1 if len(labels) else 0
    if n < 2:
        return out
    ij = np.floor(uvh[:, :2] / cell_m).astype(np.int64)
    ij -= ij.min(axis=0)
    key = ij[:, 0] * (int(ij[:, 1].max()) + 1) + ij[:, 1]
    members = [np.flatnonzero(labels == k) for k in range(n)]
    cells = [np.unique(key[m]) for m in members]
    tops = [float(np.percentile(uvh[m, 2], 95)) if len(m) else 0.0 for m in members]
    sizes = np.array([len(c) for c in cells])
    if eligible is not None:
        sizes[np.setdiff1d(np.arange(n), np.asarray(eligible, dtype=np.int64))] = 0
    for k in np.argsort(sizes, kind="stable"):
        if sizes[k] == 0:
            continue
        for other in np.argsort(-sizes, kind="stable"):
            if (sizes[other] <= sizes[k] or other == k
                    or tops[k] > tops[other] + tolerance_m):
                continue
            shared = np.intersect1d(cells[k], cells[other], assume_unique=True).size
            if shared >= share * sizes[k]:
                out[out == k] = other
                cells[other] = np.union1d(cells[other], cells[k])
                sizes[other], sizes[k] = len(cells[other]), 0
                break
    return out


def merge_split_tops(uvh: np.ndarray, labels: np.ndarray, cell_m: float, sliver_m: float,
                     tolerance_m: float, rel_tolerance: float, *,
                     eligible: list[int] | None = None) -> np.ndarray:
    """Labels (N,) with side-by-side pieces of one top merged: two clusters whose top views
    touch (cells of ``cell_m``, 8-neighbours), whose tops (95th percentile height) differ by
    at most ``max(tolerance_m, rel_tolerance x the higher top)``, and of which at least one
    is a sliver (the narrower side of its minimum-area rectangle below ``sliver_m``).

    A glossy top (a ceramic mug's) loses its highlight in the matcher: what is left of the
    rim is two arcs at the same height, each passing as an object (measured on the realistic
    desk). Two real objects side by side of the same height are rarely a sliver beside a
    neighbour; the smallest clusters merge first, and a merged cluster is measured again.
    Only the clusters ``eligible`` (None: all) merge; :data:`NOISE` stays."""
    out = labels.copy()
    keep = np.unique(out[out != NOISE]) if eligible is None else np.intersect1d(
        np.asarray(eligible, dtype=np.int64), out)
    if len(keep) < 2:
        return out
    ij = np.floor(uvh[:, :2] / cell_m).astype(np.int64)
    ij -= ij.min(axis=0) - 1
    shape = (int(ij[:, 0].max()) + 2, int(ij[:, 1].max()) + 2)
    parts = {int(k): _top_part(uvh, out == k, ij, shape) for k in keep}
    merged = True
    while merged:
        merged = False
        by_size = sorted(parts, key=lambda k: parts[k]["n"])
        for k in by_size:
            other = next((o for o in reversed(by_size) if o != k
                          and _same_top(parts[k], parts[o], sliver_m, tolerance_m,
                                        rel_tolerance)), None)
            if other is not None:
                out[out == k] = other
                parts[other] = _top_part(uvh, out == other, ij, shape)
                del parts[k]
                merged = True
                break
    return out


def _top_part(uvh: np.ndarray, mask: np.ndarray, ij: np.ndarray, shape) -> dict:
    """A cluster's top-view cells (dilated by one: its neighbours), top and narrower side."""
    cells = np.zeros(shape, dtype=np.uint8)
    cells[ij[mask, 0], ij[mask, 1]] = 1
    (_, _), (a, b), _ = cv2.minAreaRect(uvh[mask, :2].astype(np.float32))
    return {"cells": cells, "near": cv2.dilate(cells, np.ones((3, 3), np.uint8)),
            "top": float(np.percentile(uvh[mask, 2], 95)), "width": float(min(a, b)),
            "n": int(np.count_nonzero(mask))}


def _same_top(a: dict, b: dict, sliver_m: float, tolerance_m: float,
              rel_tolerance: float) -> bool:
    if min(a["width"], b["width"]) >= sliver_m:
        return False
    if abs(a["top"] - b["top"]) > max(tolerance_m, rel_tolerance * max(a["top"], b["top"])):
        return False
    return bool(np.any(a["near"] & b["cells"]))
