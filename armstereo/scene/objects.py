"""Measure one object (a cluster of points above the support plane) in plane coordinates.

Every object gets a gravity-aligned box: its vertical axis is the plane normal, its footprint
the minimum-area rectangle of the object's points projected onto the plane, its height the top
of the object above the plane. Steps, each guarding against a known stereo artefact:

1. **Outliers**: a statistical outlier filter in 3-D (mean distance to the ``SOR_NEIGHBOURS``
   nearest neighbours more than ``SOR_MEDIAN_FACTOR`` times the cluster's median) drops stray
   points and sparse streaks, which would otherwise widen the footprint. The limit is relative
   to the median, not mean + k sigma: on a clean, regular cloud the latter strips the whole rim
   (rim points have fewer close neighbours), shrinking every footprint by a point spacing. It
   does not trim by percentiles either, which would shrink round footprints (the 0.5 %
   quantiles of a disc lie 2 mm inside a 10 cm disc).
2. **Top**: a flat top (box, cylinder) shows as a sharp peak of the heights; the top is the
   median of the highest such peak (immune to the mismatches that scatter above and below an
   edge), unless more than a few per cent of the points stand clearly above it. Otherwise (a
   curved top) it is the ``TOP_PERCENTILE`` of the heights (see :func:`top_height`).
3. **Sphere**: one view sees a ball's upper cap only, and stereo loses its steep rim, so the
   footprint of a ball seen from above is several mm too small. If a least-squares sphere fits
   the points (``SPHERE_INLIER_SHARE`` within the noise band) and agrees with the footprint
   and the top, the object is reported as a sphere and its footprint is the fitted diameter.

Coordinates are the plane frame's (u, v, h) (see :mod:`armstereo.scene.plane`), metres.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np
from scipy.spatial import cKDTree

SOR_NEIGHBOURS = 8
SOR_MEDIAN_FACTOR = 2.0  # a point whose neighbours are this much farther than usual is an outlier
SOR_STAT_SAMPLE = 4000  # points whose neighbour distances set the outlier limit
RIM_CELL_M = 0.002  # raster for finding the footprint's rim
RIM_CELLS = 3  # rim width in cells (points deeper inside cannot move the footprint)
TOP_PERCENTILE = 99.5
PEAK_HALF_WIDTH_M = 0.001  # half width of a flat top's peak (at least this, or 3x noise)
PEAK_BIN_M = 0.0005
FLAT_PEAK_SHARE = 0.10  # a flat top puts this share of the object's points in one bin
MAX_ABOVE_SHARE = 0.03  # more points than this above the flat level: not the top
SPHERE_INLIER_SHARE = 0.6
SPHERE_BAND_M = 0.001  # sphere inliers lie this close to the surface (or 3x noise)
SPHERE_FOOTPRINT_RATIO = (0.85, 1.3)  # fitted diameter / measured footprint length
SPHERE_TOP_TOLERANCE_M = 0.003  # fitted top vs measured top
SPHERE_MIN_POINTS = 30


@dataclass(frozen=True)
class ObjectShape:
    """Geometry of one object in plane coordinates: footprint centre (u, v), ``length`` >=
    ``width`` of the footprint, ``angle`` of the length axis from the plane's u axis (rad),
    ``height`` of the top above the plane, ``model`` ("box" or "sphere"), ``top`` ("flat" or
    "curved"), ``radius`` (sphere only), ``kept`` mask of the points that survived the
    outlier filter, ``measured_size`` the measured footprint rectangle (length, width) (for a
    sphere, ``length`` and ``width`` are the fitted diameter instead)."""

    @property
    def measured_width(self) -> float:
        return self.measured_size[1]

    center_uv: tuple[float, float]
    length: float
    width: float
    angle: float
    height: float
    model: str
    top: str
    radius: float | None
    kept: np.ndarray
    measured_size: tuple[float, float]  # footprint rectangle (length, width), whatever the model

    def corners_uv(self) -> np.ndarray:
        """Footprint corners (4, 2) in plane coordinates, counter-clockwise."""
        c, s = math.cos(self.angle), math.sin(self.angle)
        ax, ay = np.array([c, s]) * self.length / 2, np.array([-s, c]) * self.width / 2
        ctr = np.asarray(self.center_uv)
        return np.array([ctr - ax - ay, ctr + ax - ay, ctr + ax + ay, ctr - ax + ay])


def measure_shape(uvh: np.ndarray, noise_m: float = 0.0) -> ObjectShape:
    """Footprint, top and model of one cluster (module doc). ``uvh`` (N, 3) plane coordinates
    (m); ``noise_m`` the cloud's noise level (the support plane's RMS) widens the bands."""
    kept = outlier_mask(uvh)
    p = uvh[kept]
    height, top = top_height(p[:, 2], noise_m)
    (cu, cv), length, width, angle = footprint_rectangle(p[:, :2])
    sphere = fit_sphere(p, noise_m)
    if sphere is not None and _sphere_agrees(sphere, length, height):
        (su, sv, _), r = sphere
        return ObjectShape((su, sv), 2 * r, 2 * r, 0.0, height, "sphere", top, r, kept,
                           (length, width))
    return ObjectShape((cu, cv), length, width, angle, height, "box", top, None, kept,
                       (length, width))


def outlier_mask(points: np.ndarray, *, seed: int = 0) -> np.ndarray:
    """True for points whose mean distance to their ``SOR_NEIGHBOURS`` nearest neighbours is
    not an outlier (above ``SOR_MEDIAN_FACTOR`` times its median over the cluster).

    Only points near the footprint's rim can move the footprint, so only those are tested
    (the rest are kept); the mean and std come from a seeded sample of the whole cluster, so
    the limit is the same as when every point is tested, at a fraction of the cost.
    """
    n = len(points)
    if n <= SOR_NEIGHBOURS + 1:
        return np.ones(n, dtype=bool)
    tree = cKDTree(points)
    rng = np.random.default_rng(seed)
    sample = points[rng.choice(n, size=min(n, SOR_STAT_SAMPLE), replace=False)]
    ref = tree.query(sample, k=SOR_NEIGHBOURS + 1)[0][:, 1:].mean(axis=1)
    limit = SOR_MEDIAN_FACTOR * float(np.median(ref))
    rim = np.flatnonzero(_rim_points(points[:, :2]))
    keep = np.ones(n, dtype=bool)
    if len(rim):
        d = tree.query(points[rim], k=SOR_NEIGHBOURS + 1)[0][:, 1:].mean(axis=1)
        keep[rim[d > limit]] = False
    return keep


def _rim_points(uv: np.ndarray) -> np.ndarray:
    """True for points within ``RIM_CELLS`` raster cells of the footprint's outline."""
    ij = np.floor((uv - uv.min(axis=0)) / RIM_CELL_M).astype(np.int64) + RIM_CELLS + 1
    shape = (int(ij[:, 1].max()) + RIM_CELLS + 2, int(ij[:, 0].max()) + RIM_CELLS + 2)
    occupied = np.zeros(shape, dtype=np.uint8)
    occupied[ij[:, 1], ij[:, 0]] = 1
    size = 2 * RIM_CELLS + 1
    inner = cv2.erode(occupied, np.ones((size, size), np.uint8))
    return inner[ij[:, 1], ij[:, 0]] == 0


def top_height(h: np.ndarray, noise_m: float = 0.0) -> tuple[float, str]:
    """(top height, "flat" | "curved") of heights ``h`` (m) above the plane (module doc).

    The flat level is the highest histogram bin holding ``FLAT_PEAK_SHARE`` of the points,
    refined to the median of the points within the peak's half width; it stands only if at
    most ``MAX_ABOVE_SHARE`` of the points lie clearly above it (else something real, not
    scattered mismatches, stands higher, and the top is the ``TOP_PERCENTILE``).
    """
    hi = float(np.percentile(h, TOP_PERCENTILE))
    half = max(PEAK_HALF_WIDTH_M, 3 * noise_m)
    edges = np.arange(float(h.min()), float(h.max()) + 2 * PEAK_BIN_M, PEAK_BIN_M)
    counts, edges = np.histogram(h, bins=edges)
    peaks = np.flatnonzero(counts >= FLAT_PEAK_SHARE * len(h))
    if len(peaks) == 0:
        return hi, "curved"
    level = 0.5 * (edges[peaks[-1]] + edges[peaks[-1] + 1])
    for _ in range(2):
        level = float(np.median(h[np.abs(h - level) <= half]))
    if np.mean(h > level + 2 * half) > MAX_ABOVE_SHARE:
        return hi, "curved"
    return level, "flat"


def footprint_rectangle(uv: np.ndarray):
    """((cu, cv), length, width, angle) of the minimum-area rectangle of ``uv`` (N, 2, m);
    ``angle`` (rad) is the direction of the long side from the u axis, in (-pi/2, pi/2]."""
    (cu, cv), (w, h), deg = cv2.minAreaRect(np.asarray(uv, dtype=np.float32))
    a = math.radians(deg)
    if h > w:  # OpenCV's angle belongs to the side of length w
        w, h, a = h, w, a + math.pi / 2
    a = (a + math.pi / 2) % math.pi - math.pi / 2
    if a <= -math.pi / 2 + 1e-12:
        a += math.pi
    return (float(cu), float(cv)), float(w), float(h), a


def fit_sphere(p: np.ndarray, noise_m: float = 0.0):
    """((cu, cv, ch), r) of a least-squares sphere through ``p`` (N, 3), refit on its
    inliers; None when too few points or too few inliers lie on it."""
    if len(p) < SPHERE_MIN_POINTS:
        return None
    band = max(SPHERE_BAND_M, 3 * noise_m)
    keep = np.ones(len(p), dtype=bool)
    for _ in range(3):
        sol = _algebraic_sphere(p[keep])
        if sol is None:
            return None
        c, r = sol
        res = np.abs(np.linalg.norm(p - c, axis=1) - r)
        keep = res <= max(band, 3 * float(np.sqrt(np.mean(res[keep] ** 2))))
        if keep.sum() < SPHERE_MIN_POINTS:
            return None
    if np.mean(res <= band) < SPHERE_INLIER_SHARE:
        return None
    return (float(c[0]), float(c[1]), float(c[2])), float(r)


def _algebraic_sphere(p: np.ndarray):
    """|x|^2 = 2 c.x + (r^2 - |c|^2), linear in c and the constant."""
    mean = p.mean(axis=0)
    q = p - mean  # centred for conditioning
    A = np.column_stack([2 * q, np.ones(len(q))])
    b = (q ** 2).sum(axis=1)
    # normal equations by einsum: a tall 4-wide lstsq goes through threaded BLAS (slow here)
    try:
        x = np.linalg.solve(np.einsum("ki,kj->ij", A, A), np.einsum("ki,k->i", A, b))
    except np.linalg.LinAlgError:
        return None
    r2 = x[3] + x[:3] @ x[:3]
    if not np.isfinite(r2) or r2 <= 0:
        return None
    return x[:3] + mean, float(np.sqrt(r2))


def _sphere_agrees(sphere, length: float, height: float) -> bool:
    (_, _, ch), r = sphere
    lo, hi = SPHERE_FOOTPRINT_RATIO
    return (lo * length <= 2 * r <= hi * length
            and abs(ch + r - height) <= SPHERE_TOP_TOLERANCE_M)
