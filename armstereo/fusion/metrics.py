"""Score a fused model against exact scene truth, the way multi-view benchmarks do.

- **Accuracy** (DTU "data to surface"): distance from each reconstructed point to the true
  surface, exact (:meth:`SceneTruth.distance`); reported as the mean in mm and the shares within
  1, 2 and 5 mm (ETH3D's "accuracy" at those tolerances).
- **Completeness** (DTU "surface to data"): distance from each point of the *visible* true
  surface to the nearest reconstructed point; mean in mm and shares within 1, 2 and 5 mm
  (ETH3D's "completeness"). The visible surface is sampled from the recorded ground-truth depth
  maps: the pixels of each pair's two views that the other view of the pair sees too (what a
  stereo pair can reconstruct at all, like DTU's observability mask), inside the region of
  interest, thinned to one point per ``REFERENCE_SPACING_M`` cube.
- **F1** at 1, 2 and 5 mm: harmonic mean of the two shares (ETH3D).
- **Visible surface covered**: share of everything any recorded image saw (both views of every
  pair, no stereo-visibility requirement) that lies within ``COVERAGE_TOLERANCE_M`` of the
  model: how much of what the camera looked at made it into the model.

As in DTU's evaluation, distances beyond ``OUTLIER_DISTANCE_M`` are left out of the means
(``outliers`` and ``holes`` give their shares) so that a few stray points do not decide the
mean; the shares within 1/2/5 mm count them as misses.

A mesh is scored as a surface, not as a point sample: accuracy is evaluated at every
triangle's centroid and weighted by the triangle's area (a midpoint-rule integral over the
surface: every square millimetre counts the same, however the triangles are cut), and
completeness distances are exact point-to-triangle distances to the nearest of the
``CANDIDATE_TRIANGLES`` triangles whose centroids are nearest (no sampling bias, which with
0.5 mm point samples alone is about 0.25 mm). Point clouds (raw pairs, the fused cloud) are
scored point by point.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass

import numpy as np
from numba import njit

from armstereo.errors import ConfigError
from armstereo.evaluation.depth import OCCLUSION_TOLERANCE
from armstereo.evaluation.scene_truth import SceneTruth
from armstereo.fusion.frames import seen_by, view_surface_points
from armstereo.fusion.mesh import Mesh
from armstereo.fusion.tsdf import Roi
from armstereo.recording import Pair

TOLERANCES_MM = (1, 2, 5)
OUTLIER_DISTANCE_M = 0.020  # DTU's cut-off for the means
REFERENCE_SPACING_M = 0.001  # one reference point per 1 mm cube of visible surface
COVERAGE_TOLERANCE_M = 0.005
REFERENCE_STRIDE_PX = 2
MAX_SCORED_POINTS = 2_000_000  # larger clouds are thinned (evenly, deterministically)
CANDIDATE_TRIANGLES = 8  # nearest triangles (by centroid) searched for a point's distance
DEGENERATE_AREA = 1e-12  # |ab x ac|^2 below this share of |ab|^2 |ac|^2: no area, use edges


@dataclass(frozen=True)
class Reference:
    """Points (N, 3, base) of the visible true surface, one per REFERENCE_SPACING_M cube, and
    ``stereo`` (N,): True where the cell holds a point both views of a pair see (the cell is
    then represented by such a point)."""

    points: np.ndarray
    stereo: np.ndarray

    @classmethod
    def from_sets(cls, stereo_points: np.ndarray, other_points: np.ndarray,
                  spacing: float = REFERENCE_SPACING_M) -> Reference:
        """Thin stereo-visible and other visible points together (stereo first, so a cell
        with any stereo-visible point is represented by one)."""
        stereo_points = np.asarray(stereo_points, dtype=float).reshape(-1, 3)
        pts = np.concatenate([stereo_points, np.asarray(other_points, float).reshape(-1, 3)])
        first = thin_index(pts, spacing)
        return cls(pts[first], first < len(stereo_points))

    @property
    def stereo_points(self) -> np.ndarray:
        return self.points[self.stereo]


def reference_surface(pairs: Sequence[Pair], roi: Roi, spacing: float = REFERENCE_SPACING_M,
                      stride: int = REFERENCE_STRIDE_PX) -> Reference:
    """The visible true surface inside ``roi`` from the pairs' ground-truth depth maps (every
    ``stride``-th pixel; a pixel spans about 0.8 mm at 0.5 m, so 2 still fills 1 mm cells)."""
    stereo, other = [], []
    for pair in pairs:
        views = (pair.left, pair.right)
        for a, b in (views, views[::-1]):
            if a.depth is None or b.depth is None:
                raise ConfigError(f"pair {pair.index} has no ground-truth depth to score against")
            pts = view_surface_points(a, stride)
            pts = pts[roi.contains(pts)]
            seen = seen_by(b, pts, OCCLUSION_TOLERANCE)
            stereo.append(pts[seen])
            other.append(pts[~seen])
    return Reference.from_sets(np.concatenate(stereo), np.concatenate(other), spacing)


def thin_index(points: np.ndarray, spacing: float) -> np.ndarray:
    """Sorted indices of the first point in each ``spacing`` cube (an even density whatever
    the overlap of the views)."""
    if len(points) == 0:
        return np.zeros(0, dtype=np.int64)
    cells = np.floor(points / spacing).astype(np.int64)
    cells -= cells.min(axis=0)
    span = cells.max(axis=0) + 1
    key = (cells[:, 0] * span[1] + cells[:, 1]) * span[2] + cells[:, 2]
    _, first = np.unique(key, return_index=True)
    return np.sort(first)


def thin(points: np.ndarray, spacing: float) -> np.ndarray:
    """One point (the first) per ``spacing`` cube."""
    return np.asarray(points).reshape(-1, 3)[thin_index(np.asarray(points).reshape(-1, 3),
                                                         spacing)]


def _spread(points: np.ndarray, limit: int) -> np.ndarray:
    """At most ``limit`` of the points, evenly spread over the array (deterministic)."""
    if len(points) <= limit:
        return points
    return points[np.linspace(0, len(points) - 1, limit).astype(np.int64)]


@dataclass(frozen=True)
class PointAccuracy:
    """Accuracy of a point set alone (data -> true surface)."""

    accuracy_mean_mm: float
    accuracy_median_mm: float
    within_1mm: float
    within_2mm: float
    within_5mm: float
    outliers: float
    points: int

    def as_dict(self) -> dict:
        return asdict(self)


def point_accuracy(points: np.ndarray, truth: SceneTruth,
                   weights: np.ndarray | None = None) -> PointAccuracy:
    """DTU-style accuracy of ``points`` (N, 3, base) against the exact surface; ``weights``
    (N,) make it an integral (e.g. triangle areas at their centroids)."""
    pts = np.asarray(points, dtype=float).reshape(-1, 3)
    w = np.ones(len(pts)) if weights is None else np.asarray(weights, dtype=float).reshape(-1)
    if len(w) != len(pts):
        raise ConfigError(f"{len(w)} weights for {len(pts)} points")
    keep = _spread(np.arange(len(pts)), MAX_SCORED_POINTS)
    pts, w = pts[keep], w[keep]
    if len(pts) == 0 or not w.sum() > 0:
        raise ConfigError("no reconstructed point to score")
    d = truth.distance(pts)
    near = d <= OUTLIER_DISTANCE_M
    shares = {f"within_{t}mm": _share(d <= t / 1000, w) for t in TOLERANCES_MM}
    return PointAccuracy(accuracy_mean_mm=_mean_mm(d[near], w[near]),
                         accuracy_median_mm=_weighted_median(d, w) * 1000, **shares,
                         outliers=_share(~near, w), points=len(pts))


def _share(flags: np.ndarray, w: np.ndarray) -> float:
    return float(w[flags].sum() / w.sum())


def _weighted_median(d: np.ndarray, w: np.ndarray) -> float:
    order = np.argsort(d)
    cum = np.cumsum(w[order])
    return float(d[order][np.searchsorted(cum, 0.5 * cum[-1])])


def _mean_mm(d: np.ndarray, w: np.ndarray | None = None) -> float:
    if not d.size:
        return float("nan")
    return float(np.average(d, weights=w) * 1000)


@dataclass(frozen=True)
class SurfaceScore:
    """Accuracy, completeness, F1 and coverage of a model (see the module docstring)."""

    accuracy_mean_mm: float
    accuracy_median_mm: float
    within_1mm: float
    within_2mm: float
    within_5mm: float
    completeness_mean_mm: float
    completeness_within_1mm: float
    completeness_within_2mm: float
    completeness_within_5mm: float
    chamfer_mm: float
    f1_1mm: float
    f1_2mm: float
    f1_5mm: float
    visible_surface_covered: float
    outliers: float
    holes: float
    points: int
    reference_points: int

    def as_dict(self) -> dict:
        return asdict(self)


def score_mesh(mesh: Mesh, truth: SceneTruth, reference: Reference) -> SurfaceScore:
    """Score ``mesh`` against the exact surface (accuracy, area-weighted at triangle
    centroids) and the visible reference surface (completeness, coverage)."""
    if not reference.stereo.any():
        raise ConfigError("the region of interest holds no visible true surface to score "
                          "completeness against")
    if len(mesh) == 0:
        raise ConfigError("the mesh is empty: nothing to score")
    tri = mesh.vertices[mesh.faces].astype(np.float64)  # (M, 3 corners, 3)
    acc = point_accuracy(tri.mean(axis=1), truth, weights=mesh.triangle_areas())
    d_vis = mesh_distance(tri, reference.points)
    d_comp = d_vis[reference.stereo]
    comp = {f"completeness_within_{t}mm": float(np.mean(d_comp <= t / 1000))
            for t in TOLERANCES_MM}
    comp_mean = _mean_mm(d_comp[d_comp <= OUTLIER_DISTANCE_M])
    f1 = {f"f1_{t}mm": _f1(getattr(acc, f"within_{t}mm"), comp[f"completeness_within_{t}mm"])
          for t in TOLERANCES_MM}
    return SurfaceScore(
        accuracy_mean_mm=acc.accuracy_mean_mm, accuracy_median_mm=acc.accuracy_median_mm,
        within_1mm=acc.within_1mm, within_2mm=acc.within_2mm, within_5mm=acc.within_5mm,
        completeness_mean_mm=comp_mean, **comp,
        chamfer_mm=(acc.accuracy_mean_mm + comp_mean) / 2, **f1,
        visible_surface_covered=float(np.mean(d_vis <= COVERAGE_TOLERANCE_M)),
        outliers=acc.outliers, holes=float(np.mean(d_comp > OUTLIER_DISTANCE_M)),
        points=acc.points, reference_points=int(reference.stereo.sum()))


def mesh_distance(triangles: np.ndarray, points: np.ndarray,
                  candidates: int = CANDIDATE_TRIANGLES) -> np.ndarray:
    """Distance (N,) from each point (N, 3) to the nearest of ``triangles`` (M, 3, 3) among the
    ``candidates`` whose centroids are nearest the point (exact for small, even triangles
    such as marching cubes makes)."""
    from scipy.spatial import cKDTree  # scipy comes with scikit-image

    pts = np.ascontiguousarray(points, dtype=np.float64).reshape(-1, 3)
    if len(pts) == 0:
        return np.zeros(0)
    tri = np.ascontiguousarray(triangles, dtype=np.float64)
    k = min(candidates, len(tri))
    _, idx = cKDTree(tri.mean(axis=1)).query(pts, k=k, workers=-1)
    return _nearest_distance(pts, np.ascontiguousarray(idx.reshape(len(pts), k)), tri)


@njit(cache=True)
def _nearest_distance(points, candidates, tri):
    out = np.empty(len(points))
    for i in range(len(points)):
        best = np.inf
        for j in range(candidates.shape[1]):
            t = candidates[i, j]
            d2 = _point_triangle_sq(points[i, 0], points[i, 1], points[i, 2],
                                    tri[t, 0, 0], tri[t, 0, 1], tri[t, 0, 2],
                                    tri[t, 1, 0], tri[t, 1, 1], tri[t, 1, 2],
                                    tri[t, 2, 0], tri[t, 2, 1], tri[t, 2, 2])
            best = min(best, d2)
        out[i] = math.sqrt(best)
    return out


@njit(cache=True, inline="always")
def _sq(x, y, z):
    return x * x + y * y + z * z


@njit(cache=True, inline="always")
def _segment_sq(px, py, pz, ax, ay, az, bx, by, bz):
    """Squared distance from p to the segment a-b (a point when a == b)."""
    ux, uy, uz = bx - ax, by - ay, bz - az
    den = _sq(ux, uy, uz)
    t = 0.0
    if den > 0.0:
        t = min(1.0, max(0.0, ((px - ax) * ux + (py - ay) * uy + (pz - az) * uz) / den))
    return _sq(px - ax - t * ux, py - ay - t * uy, pz - az - t * uz)


@njit(cache=True)
def _point_triangle_sq(px, py, pz, ax, ay, az, bx, by, bz, cx, cy, cz):
    """Squared distance from p to the triangle (a, b, c), scalars only (no temporaries):
    Ericson, Real-Time Collision Detection 5.1.5, closest feature by Voronoi region. A
    degenerate triangle (no area: repeated or collinear corners) is its three edges."""
    abx, aby, abz = bx - ax, by - ay, bz - az
    acx, acy, acz = cx - ax, cy - ay, cz - az
    nx, ny, nz = aby * acz - abz * acy, abz * acx - abx * acz, abx * acy - aby * acx
    if _sq(nx, ny, nz) <= DEGENERATE_AREA * _sq(abx, aby, abz) * _sq(acx, acy, acz):
        return min(_segment_sq(px, py, pz, ax, ay, az, bx, by, bz),
                   min(_segment_sq(px, py, pz, bx, by, bz, cx, cy, cz),
                       _segment_sq(px, py, pz, cx, cy, cz, ax, ay, az)))
    apx, apy, apz = px - ax, py - ay, pz - az
    d1 = abx * apx + aby * apy + abz * apz
    d2 = acx * apx + acy * apy + acz * apz
    if d1 <= 0.0 and d2 <= 0.0:
        return _sq(apx, apy, apz)  # vertex a
    bpx, bpy, bpz = px - bx, py - by, pz - bz
    d3 = abx * bpx + aby * bpy + abz * bpz
    d4 = acx * bpx + acy * bpy + acz * bpz
    if d3 >= 0.0 and d4 <= d3:
        return _sq(bpx, bpy, bpz)  # vertex b
    vc = d1 * d4 - d3 * d2
    if vc <= 0.0 and d1 >= 0.0 and d3 <= 0.0:
        s = d1 / (d1 - d3)  # edge ab
        return _sq(apx - s * abx, apy - s * aby, apz - s * abz)
    cpx, cpy, cpz = px - cx, py - cy, pz - cz
    d5 = abx * cpx + aby * cpy + abz * cpz
    d6 = acx * cpx + acy * cpy + acz * cpz
    if d6 >= 0.0 and d5 <= d6:
        return _sq(cpx, cpy, cpz)  # vertex c
    vb = d5 * d2 - d1 * d6
    if vb <= 0.0 and d2 >= 0.0 and d6 <= 0.0:
        s = d2 / (d2 - d6)  # edge ac
        return _sq(apx - s * acx, apy - s * acy, apz - s * acz)
    va = d3 * d6 - d5 * d4
    if va <= 0.0 and (d4 - d3) >= 0.0 and (d5 - d6) >= 0.0:
        s = (d4 - d3) / ((d4 - d3) + (d5 - d6))  # edge bc
        return _sq(bpx - s * (cx - bx), bpy - s * (cy - by), bpz - s * (cz - bz))
    den = va + vb + vc
    v = vb / den  # the foot falls inside the face
    w = vc / den
    return _sq(apx - v * abx - w * acx, apy - v * aby - w * acy, apz - v * abz - w * acz)


def point_triangle_distance(p: np.ndarray, a: np.ndarray, b: np.ndarray,
                            c: np.ndarray) -> float:
    """Exact distance from point p (3,) to the triangle (a, b, c) (each (3,), metres)."""
    return math.sqrt(_point_triangle_sq(*(float(x) for x in (*p, *a, *b, *c))))


def _f1(precision: float, recall: float) -> float:
    return 0.0 if precision + recall == 0 else 2 * precision * recall / (precision + recall)
