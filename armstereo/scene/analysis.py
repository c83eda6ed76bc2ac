"""Scene analysis of a base-frame cloud: support plane, objects, height map, occupancy.

:func:`analyze_scene` runs the steps (each timed in ``SceneAnalysis.timings_s``):

1. ``plane``: RANSAC + least-squares refit of the support plane, then a refit to the median
   heights of ``plane_cell_m`` table cells at least ``plane_margin_m`` from any cell that
   stands above it (:func:`.plane.refine_from_cells`; ``plane_cell_m`` 0: off). The refined
   plane is the one reported and the one objects are measured from (heights, boxes, height
   map); which points stand above the table (step 2's band, gate, splits and merges) is still
   decided about the point refit, the plane those thresholds were measured against: about
   the refined plane, lower by 1-2 mm on the realistic desk, the 2 mm notes pad and the
   table's 4-5 mm noise bridged the tray to the keypad and the mug to a shadow fragment
   (phantoms 6 -> 9 over seeds 0-4, calibrated and true camera, both matchers);
2. ``cluster``: points more than ``plane_threshold_m`` above it, grouped by voxel connected
   components (:mod:`.cluster`); groups that are too small, too thin, too low or too sparse
   to be an object (``min_points``, ``min_size_m``, ``min_height_m``, :data:`MIN_FILL`) are
   counted as rejected: they are the stereo mismatches that collect in the shadows beside
   tall objects. Two guards come first. *Gate*: a point above the threshold counts only where
   the median height of its ``gate_cell_m`` cell clears ``gate_height_m``; on a low-texture
   table single points scatter well above the 5 mm band (Birchfield-Tomasi on the realistic
   desk: std 5 mm per point) and chain close objects together, while 1 cm cells of bare
   table have medians within -8..+7 mm (5-95 %; 99th percentile +10.5 mm, SGBM +8.4 mm) and
   the desk's lowest real tops (15 and 20 mm) keep cell medians above 11.8 mm (1st
   percentile; measured on seeds 0-4 of the realistic cell). *Split*: a cluster whose top
   view falls apart into parts of at least ``min_size_m`` squared when eroded by
   ``split_neck_m`` is split (:func:`.cluster.split_bridged`). *Valleys*: a cluster whose
   tops (:data:`VALLEY_CELL` cells whose median height, over all points, is at least
   ``min_height_m``) fall into two or more parts over lower cells is split and the valley's
   points dropped, however wide the low band (:func:`.cluster.split_valleys`,
   ``split_valleys``): two close objects whose gap the matcher filled at a few millimetres.
   After the tests, an object within a larger one's top view and no higher joins it
   (:func:`.cluster.merge_covered`: an obliquely seen side cut off from its top), and two
   objects side by side at the same height, one of them a sliver, become one
   (:func:`.cluster.merge_split_tops`, ``merge_split_tops``: a glossy top cut in two);
3. ``objects``: a gravity-aligned box, model, colour and texture per group (:mod:`.objects`,
   :mod:`.appearance`); then the flat objects, sheets below the object band found in step 1
   from table cells' medians (:mod:`.flat`, ``flat_min_area_m2``; the plane is refit
   without them, since a sheet lifts the cell refit);
4. ``height_map`` and ``occupancy`` (:mod:`.heightmap`); objects that touch unobserved space
   reaching the edge of the map are flagged ``partial`` (cut by the field of view: their size
   and centre describe the visible part only).

:meth:`SceneAnalysis.as_dict` is the ``scene.json`` document (keys in ``docs/scene-analysis.md``).
"""

from __future__ import annotations

import math
import time
from dataclasses import asdict, dataclass, field

import cv2
import numpy as np

from armstereo.errors import ConfigError
from armstereo.scene.appearance import Appearance, appearance
from armstereo.scene.cloud import SceneCloud
from armstereo.scene.cluster import (
    NOISE,
    merge_covered,
    merge_split_tops,
    split_bridged,
    split_valleys,
    voxel_clusters,
)
from armstereo.scene.flat import flat_regions
from armstereo.scene.heightmap import HeightMap, Occupancy, height_map, occupancy
from armstereo.scene.objects import ObjectShape, footprint_rectangle, measure_shape
from armstereo.scene.plane import (
    SupportPlane,
    fit_support_plane,
    refine_from_cells,
    unit_up,
)

FORMAT = "armstereo.scene/1"
PARTIAL_RING_CELLS = 2
MIN_PATCH_SHARE = 0.5
# An object's points per footprint area, relative to the table's: a surface seen from above
# fills its footprint (measured 1.35-1.7 for the mock scene's objects in one pair, which are
# closer to the camera than the table; about 0.8 for a round top in an evenly sampled cloud),
# mismatch fragments are sparse streaks (0.51 for the largest one seen, seed 1 of the demo).
MIN_FILL = 0.6  # height-map cells around an object searched for unobserved space
# plane cells whose median height (of every point, the table's too) decides whether they are
# an object's top for split_valleys (m)
VALLEY_CELL = 0.01
# the points of a split cluster kept with its parts: those in the parts' own cells (m; the
# valley's points, 3-12 mm mismatches on the realistic desk, widened the tray by 4 cm when
# the parts took those within 15 mm)
VALLEY_REACH = 0.5 * VALLEY_CELL
# a cluster whose top-view cells (VALLEY_CELL) are this share inside a larger one's joins it
COVERED_SHARE = 0.5
# side-by-side pieces of one top (merge_split_tops): one of them narrower than this (m), tops
# within plane_threshold_m or this share of the higher one. The realistic desk's mug halves
# were 22-33 mm wide at the same height (within 3 mm of 90); its narrowest real objects are
# 70-80 mm across
SPLIT_TOP_SLIVER = 0.035
SPLIT_TOP_SHARE = 0.05


@dataclass(frozen=True)
class SceneOptions:
    """Analysis settings (metres, degrees). See ``docs/scene-analysis.md`` for each one."""

    up: tuple[float, float, float] = (0.0, 0.0, 1.0)
    max_tilt_deg: float = 10.0
    plane_threshold_m: float = 0.005
    ransac_iterations: int = 300
    # the plane's refit to cell medians (module doc, step 1): cell edge (0: off) and the
    # margin kept from cells standing above the plane
    plane_cell_m: float = 0.03
    plane_margin_m: float = 0.01
    max_height_m: float = 1.0
    cluster_voxel_m: float = 0.005
    min_voxel_points: int = 2
    min_points: int = 50
    min_size_m: float = 0.02
    min_height_m: float = 0.01
    cell_m: float = 0.005
    occupancy_cell_m: float = 0.02
    # a point seeds an object only where the median height of its gate cell clears
    # gate_height_m (module doc, step 2); 0 (the default) switches the gate off: 0.008 finds
    # the realistic desk's keypad but costs up to a cell of footprint on the mock table
    gate_cell_m: float = 0.01
    gate_height_m: float = 0.0
    # clusters joined by bridges narrower than twice this are split (0: never)
    split_neck_m: float = 0.015
    # clusters whose tops (cells with median height >= min_height_m) fall apart over a low
    # valley are split, the valley's points dropped (False: never)
    split_valleys: bool = True
    # objects side by side at the same height, one of them a sliver, are one object cut in
    # two (a glossy top's lost highlight; False: never merged)
    merge_split_tops: bool = True
    # flat objects (sheets below the object band, :mod:`.flat`): connected cells of
    # flat_cell_m whose median stands flat_height_m or more above the table, at least
    # flat_margin_m from anything in the band, covering flat_min_area_m2 (0: off)
    flat_min_area_m2: float = 0.01
    flat_height_m: float = 0.001
    flat_cell_m: float = 0.02
    flat_margin_m: float = 0.03
    seed: int = 0

    def check(self) -> None:
        """ConfigError naming the first bad setting."""
        unit_up(self.up)
        positive = ("plane_threshold_m", "max_height_m", "cluster_voxel_m", "min_size_m",
                    "min_height_m", "cell_m", "occupancy_cell_m", "max_tilt_deg")
        for name in positive:
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
                raise ConfigError(f"scene option {name} must be a positive number, got {v!r}")
        if self.max_tilt_deg >= 90:
            raise ConfigError(f"max tilt must be below 90 deg, got {self.max_tilt_deg}")
        for name in ("ransac_iterations", "min_voxel_points", "min_points"):
            if int(getattr(self, name)) < 1:
                raise ConfigError(f"scene option {name} must be at least 1")
        for name in ("gate_cell_m", "gate_height_m", "split_neck_m", "plane_cell_m",
                     "plane_margin_m", "flat_min_area_m2", "flat_height_m", "flat_margin_m"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v >= 0):
                raise ConfigError(f"scene option {name} must be a non-negative number, got "
                                  f"{v!r}")
        for name in ("split_valleys", "merge_split_tops"):
            if not isinstance(getattr(self, name), bool):
                raise ConfigError(f"scene option {name} must be true or false, got "
                                  f"{getattr(self, name)!r}")
        if self.flat_min_area_m2 > 0 and not (math.isfinite(self.flat_cell_m)
                                              and self.flat_cell_m > 0):
            raise ConfigError("scene option flat_cell_m must be positive when flat objects are "
                              "searched (flat_min_area_m2 > 0)")
        if self.gate_height_m > 0 and self.gate_cell_m <= 0:
            raise ConfigError("scene option gate_cell_m must be positive when the gate is on")
        if self.occupancy_cell_m < self.cell_m:
            raise ConfigError(f"the occupancy cell ({self.occupancy_cell_m} m) must not be "
                              f"finer than the height-map cell ({self.cell_m} m)")


@dataclass(frozen=True)
class SceneObject:
    """One object, base frame, metres: ``center_m`` the centre of its gravity-aligned box
    (footprint centre, half its height above the plane), ``size_m`` (length >= width of the
    footprint, height), ``yaw_deg`` of the length axis about base z in (-90, 90],
    ``height_m`` of its top above the plane, ``footprint_m`` (4, 3) the footprint corners on
    the plane."""

    id: int
    center_m: np.ndarray
    size_m: tuple[float, float, float]
    yaw_deg: float
    height_m: float
    points: int
    model: str
    top: str
    partial: bool
    radius_m: float | None
    footprint_m: np.ndarray
    appearance: Appearance | None

    def as_dict(self) -> dict:
        d = {"id": self.id, "center_m": _r(self.center_m), "size_m": _r(self.size_m),
             "yaw_deg": round(self.yaw_deg, 2), "height_m": _r(self.height_m),
             "points": self.points, "model": self.model, "top": self.top,
             "partial": self.partial, "footprint_m": _r(self.footprint_m)}
        if self.radius_m is not None:
            d["radius_m"] = _r(self.radius_m)
        if self.appearance is not None:
            d.update(self.appearance.as_dict())
        return d


@dataclass
class SceneAnalysis:
    """Everything :func:`analyze_scene` found; ``as_dict`` gives ``scene.json``."""

    source: str
    points: int
    plane: SupportPlane
    objects: list[SceneObject]
    rejected_clusters: int
    height_map: HeightMap
    occupancy: Occupancy
    options: SceneOptions
    timings_s: dict[str, float] = field(default_factory=dict)

    def as_dict(self) -> dict:
        pl, hm, occ = self.plane, self.height_map, self.occupancy
        return {
            "format": FORMAT, "frame_id": "base", "units": "m", "source": self.source,
            "points": self.points,
            "plane": {"normal": _r(pl.normal, 6), "height_m": _r(pl.height_m),
                      "rms_m": _r(pl.rms_m), "tilt_deg": round(pl.tilt_deg, 4),
                      "inliers": pl.inliers, "area_m2": _r(pl.area_m2),
                      "hull_m": _r(pl.hull_base)},
            "objects": [o.as_dict() for o in self.objects],
            "rejected_clusters": self.rejected_clusters,
            "height_map": {"cell_m": _r(hm.cell_m), "rows": int(hm.heights.shape[0]),
                           "cols": int(hm.heights.shape[1]),
                           "known_share": round(hm.known_share, 4),
                           "T_base_grid": _r(hm.T_base_grid, 6)},
            "occupancy": {"cell_m": _r(occ.cell_m), "shape_zyx": list(occ.grid.shape),
                          "T_base_grid": _r(occ.T_base_grid, 6)},
            "options": {k: (list(v) if isinstance(v, tuple) else v)
                        for k, v in asdict(self.options).items()},
            "timings_s": {k: round(v, 4) for k, v in self.timings_s.items()},
        }


def _r(v, nd: int = 5):
    """Round floats (scalars or nested arrays) for JSON: 0.01 mm is plenty."""
    a = np.asarray(v, dtype=float)
    return round(float(a), nd) if a.ndim == 0 else np.round(a, nd).tolist()


def analyze_scene(cloud: SceneCloud, options: SceneOptions = SceneOptions()) -> SceneAnalysis:
    """Analyse a checked base-frame cloud (:func:`armstereo.scene.cloud.load_cloud`).

    Raises SceneError when there is no level support plane, ConfigError for bad options.
    """
    options.check()
    timings: dict[str, float] = {}
    t0 = time.perf_counter()
    fitted = fit_support_plane(cloud.points, up=options.up, max_tilt_deg=options.max_tilt_deg,
                               threshold_m=options.plane_threshold_m,
                               iterations=options.ransac_iterations, seed=options.seed)
    plane = fitted
    if options.plane_cell_m > 0:
        plane = refine_from_cells(cloud.points, fitted, cell_m=options.plane_cell_m,
                                  margin_m=options.plane_margin_m,
                                  threshold_m=options.plane_threshold_m, up=options.up,
                                  max_tilt_deg=options.max_tilt_deg)
    uvh = plane.to_plane(cloud.points)
    flats = _flat_regions(uvh, options)
    if flats and options.plane_cell_m > 0:  # a sheet lifts the cell refit: refit without it
        skip = np.zeros(len(uvh), dtype=bool)
        skip[np.concatenate(flats)] = True
        plane = refine_from_cells(cloud.points, fitted, cell_m=options.plane_cell_m,
                                  margin_m=options.plane_margin_m,
                                  threshold_m=options.plane_threshold_m, up=options.up,
                                  max_tilt_deg=options.max_tilt_deg, exclude=skip)
        uvh = plane.to_plane(cloud.points)
        flats = _flat_regions(uvh, options)
    # which points stand above the table is decided about the point refit (module doc, step 2)
    seg = uvh if plane is fitted else fitted.to_plane(cloud.points)
    timings["plane"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    band = (seg[:, 2] > options.plane_threshold_m) & (seg[:, 2] <= options.max_height_m)
    gated = band & _cell_median_above(seg, options.gate_cell_m, options.gate_height_m)
    above = np.flatnonzero(gated)
    n_core = len(above)  # the points that passed the gate; rims are appended after them
    labels = voxel_clusters(seg[above], options.cluster_voxel_m,
                            min_voxel_points=options.min_voxel_points,
                            min_cluster_points=options.min_points)
    if options.split_neck_m > 0:
        labels = split_bridged(seg[above, :2], labels, options.cell_m, options.split_neck_m,
                               options.min_size_m ** 2)
    if options.split_valleys:
        high = _cell_median_above(seg, VALLEY_CELL, options.min_height_m)[above]
        labels = split_valleys(seg[above, :2], high, labels, VALLEY_CELL,
                               options.min_size_m ** 2, VALLEY_REACH)
    if options.gate_height_m > 0:
        rim = np.flatnonzero(band & ~gated)
        rim_labels = _attach_rims(seg[above, :2], labels, seg[rim, :2], options.gate_cell_m)
        above, labels = np.r_[above, rim], np.r_[labels, rim_labels]
    timings["cluster"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    on_map = (uvh[:, 2] > -options.plane_threshold_m) & (uvh[:, 2] <= options.max_height_m)
    hmap = height_map(uvh[on_map], plane.T_base_plane, options.cell_m)
    outside = _unobserved_outside(hmap)
    timings["height_map"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    density = plane.inliers / max(plane.area_m2, 1e-9)  # table points per square metre
    accepted, rejected = _object_shapes(labels, above, n_core, uvh, plane, options, density)
    # a part of an object that the clustering cut off and that passes as an object itself
    # (an obliquely seen side) joins the object whose top view holds it; only objects are
    # merged: the rejected fragments beside objects would fatten their footprints
    eligible = [k for k, _, _ in accepted]
    merged = merge_covered(seg[above], labels, VALLEY_CELL, COVERED_SHARE,
                           options.plane_threshold_m, eligible=eligible)
    if options.merge_split_tops:  # after merge_covered: a side already joined is no sliver
        merged = merge_split_tops(seg[above], merged, VALLEY_CELL, SPLIT_TOP_SLIVER,
                                  options.plane_threshold_m, SPLIT_TOP_SHARE,
                                  eligible=eligible)
    changed = np.unique(merged[merged != labels])  # the objects that took others in
    if len(changed):
        labels = merged
        kept = [a for a in accepted if a[0] in set(labels.tolist()) and a[0] not in changed]
        again, lost = _object_shapes(labels, above, n_core, uvh, plane, options, density,
                                     only=changed)
        accepted, rejected = sorted(kept + again, key=lambda a: a[0]), rejected + lost
    objects = []
    for _, idx, shape in accepted:
        colors = None if cloud.colors_bgr is None else cloud.colors_bgr[idx][shape.kept]
        partial = _touches(hmap, outside, uvh[idx, :2])
        objects.append(_scene_object(len(objects), shape, plane, uvh[idx][shape.kept],
                                     colors, partial))
    for idx in flats:
        colors = None if cloud.colors_bgr is None else cloud.colors_bgr[idx]
        objects.append(_scene_object(len(objects), _flat_shape(uvh[idx]), plane, uvh[idx],
                                     colors, _touches(hmap, outside, uvh[idx, :2])))
    timings["objects"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    occ = occupancy(hmap, options.occupancy_cell_m, min_height=options.min_height_m)
    timings["occupancy"] = time.perf_counter() - t0
    return SceneAnalysis(cloud.source, len(cloud.points), plane, objects, rejected, hmap, occ,
                         options, timings)


def _object_shapes(labels: np.ndarray, above: np.ndarray, n_core: int, uvh: np.ndarray,
                   plane: SupportPlane, options: SceneOptions, density: float, *,
                   only: np.ndarray | None = None
                   ) -> tuple[list[tuple[int, np.ndarray, ObjectShape]], int]:
    """The clusters (``only`` these labels, None: all) that pass as objects, as ``(label,
    point indices, shape)``, and how many were rejected (too few points, too small, too low
    or too sparse: module doc, step 2). ``above``: the clustered points' indices into
    ``uvh`` (the first ``n_core`` passed the gate); ``density``: table points per square
    metre."""
    accepted, rejected = [], 0
    n_clusters = int(labels.max()) + 1 if len(labels) else 0
    order = np.argsort(labels, kind="stable")
    bounds = np.searchsorted(labels[order], np.arange(n_clusters + 1))
    min_points = _min_object_points(density, options)
    for k in (range(n_clusters) if only is None else only.tolist()):
        members = order[bounds[k]:bounds[k + 1]]
        if len(members) == 0:  # a label merged away
            continue
        idx = above[members]
        core = int(np.count_nonzero(members < n_core))  # rims alone make no object
        if core < min_points:
            rejected += 1
            continue
        shape = measure_shape(uvh[idx], plane.rms_m)
        fill = core / (shape.measured_size[0] * shape.measured_size[1] * density)
        if (shape.measured_width < options.min_size_m or shape.height < options.min_height_m
                or shape.kept.sum() < min_points or fill < MIN_FILL):
            rejected += 1
            continue
        accepted.append((k, idx, shape))
    return accepted, rejected


def _flat_regions(uvh: np.ndarray, options: SceneOptions) -> list[np.ndarray]:
    """The flat objects' point indices (:func:`.flat.flat_regions`; none when off)."""
    if options.flat_min_area_m2 <= 0:
        return []
    return flat_regions(uvh, cell_m=options.flat_cell_m, height_m=options.flat_height_m,
                        band_m=options.plane_threshold_m, margin_m=options.flat_margin_m,
                        min_area_m2=options.flat_min_area_m2)


def _flat_shape(uvh: np.ndarray) -> ObjectShape:
    """A flat object's box: the minimum-area rectangle of its points, the median height
    (a sheet's top is its heights' only level; their spread is the table's noise)."""
    (cu, cv), length, width, angle = footprint_rectangle(uvh[:, :2])
    return ObjectShape((cu, cv), length, width, angle, float(np.median(uvh[:, 2])), "box",
                       "flat", None, np.ones(len(uvh), dtype=bool), (length, width))


def _cell_median_above(uvh: np.ndarray, cell_m: float, height_m: float) -> np.ndarray:
    """True for points (N, 3 plane coordinates) in a plane cell of ``cell_m`` whose median
    height clears ``height_m``: a point seeds an object only where its neighbourhood stands
    above the table's noise (an object's rim is given back by :func:`_attach_rims`)."""
    if height_m <= 0:
        return np.ones(len(uvh), dtype=bool)
    ij = np.floor(uvh[:, :2] / cell_m).astype(np.int64)
    ij -= ij.min(axis=0) - 1
    shape = (int(ij[:, 0].max()) + 2, int(ij[:, 1].max()) + 2)
    flat = ij[:, 0] * shape[1] + ij[:, 1]
    order = np.lexsort((uvh[:, 2], flat))
    fs = flat[order]
    starts = np.flatnonzero(np.r_[True, fs[1:] != fs[:-1]])
    counts = np.diff(np.r_[starts, len(fs)])
    high = np.zeros(shape[0] * shape[1], dtype=np.uint8)
    high[fs[starts]] = uvh[order[starts + counts // 2], 2] > height_m
    return high[flat] > 0


def _attach_rims(uv: np.ndarray, labels: np.ndarray, rim_uv: np.ndarray,
                 cell_m: float) -> np.ndarray:
    """Labels (M,) for the points ``rim_uv`` (M, 2) above the plane band that the gate held
    back: the label of a clustered point (``uv``, ``labels``) in the same or a neighbouring
    ``cell_m`` cell, else NOISE. An object's rim cells are partly table, so their medians
    fail the gate; given back after clustering, the rim cannot join two objects into one."""
    out = np.full(len(rim_uv), NOISE, dtype=np.int64)
    ok = labels >= 0
    if not ok.any() or len(rim_uv) == 0:
        return out
    lo = np.minimum(uv.min(axis=0), rim_uv.min(axis=0))
    ij = np.floor((uv[ok] - lo) / cell_m).astype(np.int64) + 1
    rij = np.floor((rim_uv - lo) / cell_m).astype(np.int64) + 1
    shape = tuple(int(v) + 2 for v in np.maximum(ij.max(axis=0), rij.max(axis=0)))
    grid = np.zeros(shape, dtype=np.int32)  # label + 1 of a clustered point per cell, 0 none
    grid[ij[:, 0], ij[:, 1]] = labels[ok] + 1
    near = cv2.dilate(grid.astype(np.float32), np.ones((3, 3), np.uint8))  # any neighbour
    own = grid[rij[:, 0], rij[:, 1]]
    pick = np.where(own > 0, own, near[rij[:, 0], rij[:, 1]].astype(np.int64))
    return pick - 1


def _min_object_points(density: float, options: SceneOptions) -> int:
    """An object needs ``options.min_points`` points and at least MIN_PATCH_SHARE of what a
    ``min_size_m`` square of the table holds (``density``, points per m^2): this drops the
    sparse mismatch fragments of a dense cloud without losing objects of a sparse one."""
    return max(options.min_points, int(MIN_PATCH_SHARE * density * options.min_size_m ** 2))


def _scene_object(k: int, shape: ObjectShape, plane: SupportPlane, uvh: np.ndarray,
                  colors: np.ndarray | None, partial: bool) -> SceneObject:
    R = plane.T_base_plane[:3, :3]
    center = plane.to_base(np.array([[*shape.center_uv, shape.height / 2]]))[0]
    axis = R[:, :2] @ np.array([math.cos(shape.angle), math.sin(shape.angle)])
    yaw = 0.0 if shape.model == "sphere" else _axis_yaw_deg(axis)
    corners = np.column_stack([shape.corners_uv(), np.zeros(4)])
    look = None if colors is None else appearance(uvh[:, :2], colors)
    return SceneObject(k, center, (shape.length, shape.width, shape.height), yaw, shape.height,
                       int(len(uvh)), shape.model, shape.top, partial, shape.radius,
                       plane.to_base(corners), look)


def _axis_yaw_deg(axis_base: np.ndarray) -> float:
    """Yaw of a line (not a direction) about base z, degrees in (-90, 90]."""
    d = math.degrees(math.atan2(axis_base[1], axis_base[0])) % 180.0
    return d - 180.0 if d > 90.0 else d


def _unobserved_outside(hmap: HeightMap) -> np.ndarray:
    """Unobserved space around and in the height map, one cell wider on every side: the ring
    outside the map plus the unknown cells connected (4-neighbours) to it, i.e. space outside
    the view, as opposed to shadows enclosed by seen table."""
    unknown = np.pad((~np.isfinite(hmap.heights)).astype(np.uint8), 1, constant_values=1)
    _, comp = cv2.connectedComponents(unknown, connectivity=4)
    return comp == comp[0, 0]


def _touches(hmap: HeightMap, outside: np.ndarray, uv: np.ndarray) -> bool:
    """True when unobserved outside space lies within PARTIAL_RING_CELLS of the points."""
    rows, cols = hmap.cell_of(uv)
    mask = np.zeros(outside.shape, dtype=np.uint8)
    mask[np.clip(rows + 1, 0, outside.shape[0] - 1), np.clip(cols + 1, 0, outside.shape[1] - 1)] = 1
    size = 2 * PARTIAL_RING_CELLS + 1
    ring = cv2.dilate(mask, np.ones((size, size), np.uint8)).astype(bool)
    return bool(np.any(ring & outside))
