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
