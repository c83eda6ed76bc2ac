"""The support plane: RANSAC over a seeded sample, a least-squares (total) refit, then a refit
from the median heights of table cells away from anything standing on the table
(:func:`refine_from_cells`).

The plane is returned with its normal pointing along the expected ``up`` (base frame) and must
lie within ``max_tilt_deg`` of it: a tabletop analysed in the robot's base frame has a roughly
level table. RANSAC only accepts hypotheses that are that level, so a wall or a slanted board
with more points does not win; if no level plane has enough support, the error names the
largest plane found and its tilt, so the user can pass the right ``--up``.

Plane frame (``T_base_plane``): z = the unit normal, x = base x projected into the plane (base y
when the normal is close to base x), origin = the base origin projected onto the plane. Plane
coordinates (u, v, h) are (x, y, z) in that frame; h is the height above the plane.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from armstereo.errors import ConfigError
from armstereo.scene.errors import SceneError

RANSAC_SAMPLE = 8_000  # points scored per hypothesis (a seeded random subset; the refit
# uses every point, so the sample only has to tell good hypotheses from bad ones)
MIN_PLANE_SHARE = 0.10  # a support plane holds at least this share of the cloud
# ... and at least this share of the best plane of any tilt: a level band through an inclined
# table (a thin strip of it) must not pass for a table; a real table beside a wall does
MIN_SHARE_OF_BEST = 0.25
# A support plane has the scene on it and above it, not below it. A level plane through object
# tops on one side and the table on the other (a few degrees off) can hold as many points
# within the band as the table when the table's depth is noisy (measured: Birchfield-Tomasi on
# the realistic desk, table noise ~5 mm, a 2.9 deg plane through the tray and keypad tops won by
# 3558 to 3386 sampled inliers); it leaves a wedge of table points below it (1582 vs 149 of the
# 8000 sampled, more than 10 mm below). Hypotheses are therefore ranked by inliers minus the
# points below them, counting only points between BELOW_MIN_BANDS bands and BELOW_DEPTH_M below:
# a floor seen past the table's edge (0.75 m down in the mock) counts against no table plane.
BELOW_MIN_BANDS = 2.0
BELOW_DEPTH_M = 0.05
BELOW_WEIGHT = 1.0
REFIT_ROUNDS = 3
REFIT_SIGMAS = 3.0  # refit inliers: within this many residual RMS (never wider than RANSAC's)
MIN_REFIT_THRESHOLD_M = 0.001
# The cell refit (refine_from_cells). Measured on the realistic cell (seeds 0-4, both matchers,
# calibrated and true camera): table points scatter with a MAD sigma of 4.3 mm, so the point
# refit's +-5 mm band truncates the noise at ~1.2 sigma and holds on to a plane tilted by
# 0.1-0.35 deg (6 mm/m on seed 3, Birchfield-Tomasi) whose height, carried 0.41 m to the base
# origin, is 1.6-3.4 mm high; a wider point band (12.5 mm) tilts onto the 15 mm tray. The
# median of a 3 cm cell does not care about the tails, and cells standing above the plane
# (a 1 cm cell whose median clears the threshold, grown by a margin) are left out first.
CELL_WINDOW_BANDS = 2.0  # points within this many threshold_m of the plane enter a cell
CELL_MIN_POINTS = 10  # a cell's median counts with at least this many points
CELL_SIGMAS = 3.0  # cells kept: within this many MAD sigmas of the cell fit ...
CELL_BAND_BANDS = 2.0  # ... and never farther than this many threshold_m
CELL_ROUNDS = 3
CELL_SAMPLE = 60_000  # at most about this many points are binned into cells
EXCLUDE_CELL_M = 0.01  # the cells tested for standing above the plane
_EPS = 1e-12


@dataclass(frozen=True)
class SupportPlane:
    """A fitted plane in the base frame: ``normal`` (3,) unit, pointing up; ``height_m`` the
    plane's offset along it (``normal . p`` for any point p on the plane; for a level table,
    its z); ``rms_m`` the RMS distance of the refit's inliers; ``inliers`` their number;
    ``tilt_deg`` the angle between ``normal`` and the expected up; ``hull_uv`` (K, 2) the
    convex hull of the inliers in plane coordinates (m); ``T_base_plane`` the plane frame."""

    normal: np.ndarray
    height_m: float
    rms_m: float
    inliers: int
    tilt_deg: float
    hull_uv: np.ndarray
    T_base_plane: np.ndarray

    def heights(self, points_base: np.ndarray) -> np.ndarray:
        """Signed height (N,) of base-frame points (N, 3) above the plane (m)."""
        return _dot(points_base, self.normal) - self.height_m

    def to_plane(self, points_base: np.ndarray) -> np.ndarray:
        """Plane coordinates (N, 3) = (u, v, h) of base-frame points (N, 3)."""
        R, t = self.T_base_plane[:3, :3], self.T_base_plane[:3, 3]
        return np.einsum("ij,jk->ik", np.asarray(points_base, dtype=float) - t, R)

    def to_base(self, points_plane: np.ndarray) -> np.ndarray:
        """Base-frame points (N, 3) from plane coordinates (N, 3)."""
        R, t = self.T_base_plane[:3, :3], self.T_base_plane[:3, 3]
        return np.einsum("ij,kj->ik", np.asarray(points_plane, dtype=float), R) + t

    @property
    def hull_base(self) -> np.ndarray:
        """The inliers' convex hull (K, 3) in base, on the plane."""
        uv = np.column_stack([self.hull_uv, np.zeros(len(self.hull_uv))])
        return self.to_base(uv)

    @property
    def area_m2(self) -> float:
        return float(cv2.contourArea(self.hull_uv.astype(np.float32)))


def _dot(points: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``points @ v`` for (N, 3) points. Not BLAS: on 3-wide arrays OpenBLAS gains nothing,
    and its threads made such products 10x slower on a busy 2-core machine (measured)."""
    return np.einsum("ij,j->i", points, v)


def unit_up(up) -> np.ndarray:
    """``up`` as a unit 3-vector; ConfigError if it is not three finite numbers, not zero."""
    v = np.asarray(up, dtype=float).reshape(-1)
    if v.shape != (3,) or not np.all(np.isfinite(v)) or np.linalg.norm(v) < _EPS:
        raise ConfigError(f"up must be a non-zero 3-vector, got "
                          f"{[float(x) for x in np.ravel(up)]}")
    return v / np.linalg.norm(v)


def fit_support_plane(points: np.ndarray, *, up=(0.0, 0.0, 1.0), max_tilt_deg: float = 10.0,
                      threshold_m: float = 0.005, iterations: int = 300,
                      seed: int = 0) -> SupportPlane:
    """The dominant plane of ``points`` (N, 3, base, m) within ``max_tilt_deg`` of ``up``.

    RANSAC scores ``iterations`` three-point hypotheses on a seeded sample of
    :data:`RANSAC_SAMPLE` points (inlier distance ``threshold_m``); the best level one is refit
    by total least squares on all its inliers, with the inlier band narrowed to a few RMS.
    Hypotheses are ranked by their inliers minus the points just below them (see
    :data:`BELOW_DEPTH_M`): a support plane has the scene above it.
    Raises SceneError when no level plane holds :data:`MIN_PLANE_SHARE` of the points.
    """
    up_v = unit_up(up)
    pts = np.asarray(points, dtype=float)
    rng = np.random.default_rng(seed)
    sample = pts[rng.choice(len(pts), size=min(len(pts), RANSAC_SAMPLE), replace=False)]
    origin = sample.mean(axis=0)
    sample = sample - origin  # centred, so float32 scoring keeps sub-micrometre precision
    normals, offsets = _hypotheses(sample, iterations, rng)
    flip = np.where(normals @ up_v < 0, -1.0, 1.0)  # every normal points up
    normals, offsets = normals * flip[:, None], offsets * flip
    cos_tilt = normals @ up_v
    support, below = _support(sample, normals, offsets, threshold_m)
    level = cos_tilt >= math.cos(math.radians(max_tilt_deg))
    need = max(MIN_PLANE_SHARE * len(sample), MIN_SHARE_OF_BEST * support.max(initial=0))
    ok = level & (support >= need)
    if not np.any(ok):
        raise SceneError(_no_level_plane(normals, support, cos_tilt, need, len(sample),
                                         max_tilt_deg, up_v))
    score = support - BELOW_WEIGHT * below
    best = int(np.argmax(np.where(ok, score, -np.inf)))
    return _refit(pts, normals[best], offsets[best] + float(normals[best] @ origin),
                  threshold_m, up_v, max_tilt_deg)


def _hypotheses(sample: np.ndarray, iterations: int, rng: np.random.Generator):
    """Unit normals (K, 3) and offsets (K,) of planes through random point triples
    (degenerate triples dropped)."""
    if iterations < 1:
        raise ConfigError(f"RANSAC needs at least one iteration, got {iterations}")
    idx = rng.integers(0, len(sample), size=(iterations, 3))
    a, b, c = sample[idx[:, 0]], sample[idx[:, 1]], sample[idx[:, 2]]
    n = np.cross(b - a, c - a)
    norm = np.linalg.norm(n, axis=1)
    ok = norm > _EPS
    n = n[ok] / norm[ok, None]
    return n, np.einsum("ij,ij->i", n, a[ok])


def _support(sample: np.ndarray, normals: np.ndarray, offsets: np.ndarray,
             threshold_m: float) -> tuple[np.ndarray, np.ndarray]:
    """Per plane (K,): the number of sample points within ``threshold_m`` of it, and the
    number below it by BELOW_MIN_BANDS bands to BELOW_DEPTH_M. float32 and plain
    broadcasting: a 3-wide BLAS product is slower on a busy 2-core machine."""
    s32 = sample.astype(np.float32)
    n32, d32 = normals.astype(np.float32), offsets.astype(np.float32)
    out = np.empty(len(normals), dtype=np.int64)
    below = np.empty(len(normals), dtype=np.int64)
    lo, hi = np.float32(-BELOW_DEPTH_M), np.float32(-BELOW_MIN_BANDS * threshold_m)
    step = max(1, 2_000_000 // max(1, len(sample)))  # bound the (N, K) distance block
    for k in range(0, len(normals), step):
        n, d = n32[k:k + step], d32[k:k + step]
        dist = s32[:, 0:1] * n[:, 0]
        dist += s32[:, 1:2] * n[:, 1]
        dist += s32[:, 2:3] * n[:, 2]
        dist -= d
        below[k:k + step] = np.count_nonzero((dist < hi) & (dist > lo), axis=0)
        np.abs(dist, out=dist)
        out[k:k + step] = np.count_nonzero(dist < threshold_m, axis=0)
    return out, below


def _no_level_plane(normals, support, cos_tilt, need, n_sample, max_tilt_deg, up_v) -> str:
    if len(normals) == 0 or support.max() < MIN_PLANE_SHARE * n_sample:
        return (f"no support plane: no plane holds {MIN_PLANE_SHARE:.0%} of the "
                f"{n_sample} points sampled (is there a table in the cloud?)")
    k = int(np.argmax(support))
    tilt = math.degrees(math.acos(float(np.clip(cos_tilt[k], -1.0, 1.0))))
    n = normals[k]
    return (f"the largest plane (normal [{n[0]:.3f}, {n[1]:.3f}, {n[2]:.3f}], "
            f"{support[k] / n_sample:.0%} of the points) is tilted {tilt:.1f} deg from up "
            f"[{up_v[0]:.3f}, {up_v[1]:.3f}, {up_v[2]:.3f}] (limit {max_tilt_deg:g} deg): "
            "not a level table in the base frame; if the table really is inclined, pass its "
            "normal with --up X,Y,Z (or widen --max-tilt)")


def _refit(pts: np.ndarray, n: np.ndarray, d: float, threshold_m: float, up_v: np.ndarray,
           max_tilt_deg: float) -> SupportPlane:
    cols = np.ascontiguousarray(pts.T)  # (3, N): contiguous rows make every pass below cheap
    band = threshold_m
    for _ in range(REFIT_ROUNDS):
        inl = cols[:, np.abs(_combine(n, cols) - d) < band]
        if inl.shape[1] < 3:
            raise SceneError("no support plane: the RANSAC plane lost its inliers in the refit")
        centroid = inl.mean(axis=1)
        q = inl - centroid[:, None]
        _, vecs = np.linalg.eigh(np.einsum("ik,jk->ij", q, q))
        n = vecs[:, 0] * (1.0 if vecs[:, 0] @ up_v >= 0 else -1.0)
        d = float(n @ centroid)
        rms = float(np.sqrt(np.mean(_combine(n, q) ** 2)))
        band = min(threshold_m, max(REFIT_SIGMAS * rms, MIN_REFIT_THRESHOLD_M))
    tilt = math.degrees(math.acos(float(np.clip(n @ up_v, -1.0, 1.0))))
    if tilt > max_tilt_deg:
        raise SceneError(f"the support plane's refit normal is tilted {tilt:.1f} deg from up "
                         f"(limit {max_tilt_deg:g} deg)")
    T = plane_frame(n, d)
    rel = inl - T[:3, 3:4]
    uv = np.column_stack([_combine(T[:3, 0], rel), _combine(T[:3, 1], rel)])
    return SupportPlane(n, d, rms, inl.shape[1], tilt, _hull(uv), T)


def refine_from_cells(points: np.ndarray, plane: SupportPlane, *, cell_m: float = 0.03,
                      margin_m: float = 0.01, threshold_m: float = 0.005, up=(0.0, 0.0, 1.0),
                      max_tilt_deg: float = 10.0,
                      exclude: np.ndarray | None = None) -> SupportPlane:
    """``plane`` refit to the median heights of ``cell_m`` cells of table (base frame, m).

    1 cm cells (:data:`EXCLUDE_CELL_M`) whose median height above ``plane`` clears
    ``threshold_m`` stand above the table (objects, their shadows' mismatches); they and every
    cell within ``margin_m`` of them are left out. The rest of the points within
    :data:`CELL_WINDOW_BANDS` bands of the plane (a fixed-stride subset of about
    :data:`CELL_SAMPLE`) are binned into ``cell_m`` cells in plane
    coordinates; the plane h = a + b u + c v is fit by least squares to the cells' (mean u,
    mean v, median h), keeping the cells within :data:`CELL_SIGMAS` MAD sigmas of it, and the
    whole is repeated :data:`CELL_ROUNDS` times about the new plane. Points marked in
    ``exclude`` (N,) bool are left out too (flat objects, :mod:`.flat`). ``rms_m``, ``inliers``
    and the hull are those of the points within the original refit band of the new plane, as
    for :func:`fit_support_plane`. Returns ``plane`` unchanged when fewer than 3 cells remain.
    """
    up_v = unit_up(up)
    pts = np.asarray(points, dtype=float)
    cols = np.ascontiguousarray(pts.T)
    R, t = plane.T_base_plane[:3, :3], plane.T_base_plane[:3, 3]
    rel = cols - t[:, None]
    uvh = np.stack([_combine(R[:, 0], rel), _combine(R[:, 1], rel), _combine(R[:, 2], rel)])
    left_out = _above_cells(uvh, EXCLUDE_CELL_M, threshold_m, margin_m)
    keep = np.flatnonzero(~left_out if exclude is None else ~(left_out | exclude))
    # a fixed stride: a 3 cm cell of the realistic desk holds ~1000 table points, a few
    # hundred give its median to a fraction of the table's correlated error
    kept = cols[:, keep[::max(1, len(keep) // CELL_SAMPLE)]]
    n, d = plane.normal, plane.height_m
    window = CELL_WINDOW_BANDS * threshold_m
    cap = CELL_BAND_BANDS * threshold_m
    for _ in range(CELL_ROUNDS):
        T = plane_frame(n, d)
        rel = kept - T[:3, 3:4]
        h = _combine(T[:3, 2], rel)
        near = np.abs(h) < window
        u, v, h = _combine(T[:3, 0], rel[:, near]), _combine(T[:3, 1], rel[:, near]), h[near]
        fit = _cell_plane(u, v, h, cell_m, cap)
        if fit is None:
            return plane
        a, b, c = fit
        n_new = T[:3, :3] @ np.array([-b, -c, 1.0])
        n = n_new / np.linalg.norm(n_new)
        d = float(n @ (T[:3, 3] + a * T[:3, 2]))
    tilt = math.degrees(math.acos(float(np.clip(n @ up_v, -1.0, 1.0))))
    if tilt > max_tilt_deg:
        return plane  # the cells disagree with the level check: keep the checked plane
    band = min(threshold_m, max(REFIT_SIGMAS * plane.rms_m, MIN_REFIT_THRESHOLD_M))
    dist = _combine(n, cols) - d
    inl = np.abs(dist) < band
    if np.count_nonzero(inl) < 3:
        return plane
    rms = float(np.sqrt(np.mean(dist[inl] ** 2)))
    T = plane_frame(n, d)
    rel = cols[:, inl] - T[:3, 3:4]
    uv = np.column_stack([_combine(T[:3, 0], rel), _combine(T[:3, 1], rel)])
    return SupportPlane(n, d, rms, int(np.count_nonzero(inl)), tilt, _hull(uv), T)


def _above_cells(uvh: np.ndarray, cell_m: float, height_m: float,
                 margin_m: float) -> np.ndarray:
    """True for points ((3, N) plane coordinates) in a ``cell_m`` cell whose median height
    clears ``height_m``, or within ``margin_m`` of such a cell. The median of a cell's k
    points clears it when at least k - k // 2 of them do: counts, no sort."""
    ij = np.floor(uvh[:2] / cell_m).astype(np.int64)
    ij -= ij.min(axis=1, keepdims=True)
    shape = (int(ij[0].max()) + 1, int(ij[1].max()) + 1)
    flat = ij[0] * shape[1] + ij[1]
    total = np.bincount(flat, minlength=shape[0] * shape[1])
    high = np.bincount(flat[uvh[2] > height_m], minlength=shape[0] * shape[1])
    mark = ((total > 0) & (high >= total - total // 2)).astype(np.uint8).reshape(shape)
    r = int(math.ceil(margin_m / cell_m - 1e-9))
    if r > 0:
        mark = cv2.dilate(mark, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1,) * 2))
    return mark.reshape(-1)[flat] > 0


def _cell_plane(u: np.ndarray, v: np.ndarray, h: np.ndarray, cell_m: float,
                cap: float) -> tuple[float, float, float] | None:
    """(a, b, c) of h = a + b u + c v (plane coordinates, m) fit to the median heights of
    the ``cell_m`` cells holding CELL_MIN_POINTS, three rounds keeping the cells within
    CELL_SIGMAS MAD sigmas (at most ``cap``); None with fewer than 3 such cells (the last
    fit when a later round keeps fewer)."""
    if len(h) < 3:
        return None
    iu, iv = np.floor(u / cell_m).astype(np.int64), np.floor(v / cell_m).astype(np.int64)
    iu -= iu.min()
    iv -= iv.min()
    flat = iu * (int(iv.max()) + 1) + iv
    order = np.lexsort((h, flat))
    fs = flat[order]
    starts = np.flatnonzero(np.r_[True, fs[1:] != fs[:-1]])
    counts = np.diff(np.r_[starts, len(fs)])
    ok = counts >= CELL_MIN_POINTS
    med = h[order[starts + counts // 2]][ok]
    cu = (np.add.reduceat(u[order], starts) / counts)[ok]
    cv = (np.add.reduceat(v[order], starts) / counts)[ok]
    sel = np.abs(med) < cap
    coef = None
    for _ in range(3):
        if np.count_nonzero(sel) < 3:
            break
        A = np.column_stack([np.ones(np.count_nonzero(sel)), cu[sel], cv[sel]])
        coef = np.linalg.lstsq(A, med[sel], rcond=None)[0]
        res = med - (coef[0] + coef[1] * cu + coef[2] * cv)
        sigma = 1.4826 * float(np.median(np.abs(res[sel])))
        sel = np.abs(res) < min(cap, max(CELL_SIGMAS * sigma, 0.1 * cap))
    return None if coef is None else (float(coef[0]), float(coef[1]), float(coef[2]))


def _combine(v: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """``v @ rows`` for a 3-vector and (3, N) rows, without BLAS (see :func:`_dot`)."""
    return v[0] * rows[0] + v[1] * rows[1] + v[2] * rows[2]


def _hull(uv: np.ndarray) -> np.ndarray:
    """Convex hull (K, 2) of plane points ``uv`` (N, 2)."""
    return cv2.convexHull(uv.astype(np.float32)).reshape(-1, 2).astype(float)


def plane_frame(normal: np.ndarray, height: float) -> np.ndarray:
    """``T_base_plane`` for a unit ``normal`` and offset (module doc)."""
    x = np.array([1.0, 0.0, 0.0]) if abs(normal[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    x = x - (x @ normal) * normal
    x /= np.linalg.norm(x)
    T = np.eye(4)
    T[:3, 0], T[:3, 1], T[:3, 2] = x, np.cross(normal, x), normal
    T[:3, 3] = height * normal
    return T
