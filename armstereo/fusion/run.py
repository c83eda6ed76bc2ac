"""Fuse every stereo pair of a recording into one model: ``fuse_recording``.

Stages (each timed in the report's ``timings_s``): ``read`` (open the recording),
``reconstruct`` (rectify, match, triangulate every pair; on worker processes when there are
several cores), ``roi`` (the region of interest, given or found), ``filter`` (each depth map
weighted by its local noise and fitted, :mod:`armstereo.fusion.depth_filter`), ``integrate``
(TSDF), ``extract`` (marching cubes), ``support`` (which pairs see each vertex: colours and
the fused cloud's second-view rule), ``write`` (mesh.ply, fused.ply, fusion.mcap) and, with ground
truth, ``score``.

Outputs in ``out_dir``: ``mesh.ply`` (coloured triangles, base frame, m), ``fused.ply`` (the
mesh vertices that at least ``min_views`` pairs see within the support tolerance; a surface
seen by one pair only stays in the mesh but not in the cloud), ``fusion.mcap`` (see
:mod:`armstereo.fusion.foxglove`) and ``report.json`` (the returned report).
"""

from __future__ import annotations

import dataclasses
import json
import logging
import math
import multiprocessing
import os
import resource
import time
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from armstereo import __version__
from armstereo.errors import ConfigError, RecordingError
from armstereo.evaluation.scene_truth import SceneTruth
from armstereo.fusion.depth_filter import DepthFilterOptions, default_filter, filter_frame
from armstereo.fusion.foxglove import ViewPose, write_fusion_mcap
from armstereo.fusion.frames import frame_from_reconstruction, frame_from_truth
from armstereo.fusion.mesh import extract_mesh, fused_cloud
from armstereo.fusion.mesh_ply import write_mesh_ply
from armstereo.fusion.metrics import point_accuracy, reference_surface, score_mesh
from armstereo.fusion.roi import auto_roi, check_roi_seen, frame_points
from armstereo.fusion.tsdf import DepthFrame, Roi, TsdfVolume
from armstereo.io.ply import write_ply
from armstereo.photometric.correct import as_options, for_recording
from armstereo.reconstruct.stereo_options import (
    BirchfieldOptions,
    StereoOptions,
    matcher_record,
    resolve_matcher,
)
from armstereo.recording import Recording
from armstereo.recording.remount import remounted

log = logging.getLogger(__name__)

DEFAULT_VOXEL_M = 0.002
TRUNC_VOXELS = 4  # default truncation: 4 voxels (8 mm at 2 mm), about 3 sigma of stereo noise
# Behind an observed surface only half the truncation is updated, and a pair "sees" a vertex
# within a quarter of it (one voxel by default): with the whole truncation behind and half of
# it as the tolerance, the fused top of a box grew a lip over its edges that the pairs looking
# across the top confirmed, and the fused cloud's footprints came out 4-8 mm too wide
# (bench/results/fused_footprint.md).
BEHIND_TRUNC = 0.5
SUPPORT_TOLERANCE_TRUNC = 0.25
DEFAULT_MIN_VIEWS = 2
# Weight a meshed cube's corners need with the depth filter's weights: the summed weight W
# predicts the fused error, ~sigma0 / sqrt(W) rms; 0.05 keeps surface within ~4.5 mm rms (the
# 5 mm completeness tolerance); 0.02 (~7 mm) kept the table's few-view borders, a third of the
# mean error (seeds 0-4: 1.18 -> 0.96 mm, 98.2 -> 96.7 %; docs/fusion.md). No filter: 1.0.
DEFAULT_MIN_WEIGHT = 0.05
RAW_POINTS_PER_PAIR = 30_000  # raw points kept per pair (random subset): ROI and raw scoring
METADATA_SCENE_TRUTH = "scene_truth"
DEPTH_SOURCES = ("stereo", "truth")
CORES_PER_WORKER = 2
OUTPUT_NAMES = {"mesh": "mesh.ply", "cloud": "fused.ply", "mcap": "fusion.mcap",
                "report": "report.json"}


@dataclass(frozen=True)
class FusionOptions:
    """How to fuse. ``trunc`` None = TRUNC_VOXELS voxels; ``roi`` None = found from the views
    (:func:`armstereo.fusion.roi.auto_roi`); ``workers`` None = :func:`default_workers`, 1 =
    reconstruct in this process (more: worker processes, started with ``spawn``, so a script
    calling this needs the ``if __name__ == "__main__":`` guard); ``depth_source`` ``truth``
    fuses the mock camera's ground-truth depth instead of stereo (a plumbing check);
    ``score`` False skips scoring against scene truth; ``stereo`` says how each pair is
    matched (:class:`~armstereo.reconstruct.stereo_options.BirchfieldOptions`, e.g.
    ``BirchfieldOptions(photo_check=CLEAN_PHOTO_CHECK)`` for clean mock views, or
    ``SgbmOptions``), or ``method`` (None: ``stereo``'s, else "birchfield") with the older
    ``stereo_options`` dict of the matcher's keywords (:attr:`matcher` resolves them);
    ``photometric``: what is corrected before matching (True, False or
    ``armstereo.photometric.PhotometricOptions``; the vignetting model is the recording's
    mount file's); ``mount`` (a CameraMount) reconstructs every pair as if the camera had that
    mount instead of the recorded one (:mod:`armstereo.recording.remount`; its vignetting then
    applies); ``depth_filter`` how each depth map is weighted and fitted before fusion
    (:mod:`armstereo.fusion.depth_filter`; ``DepthFilterOptions(enabled=False)`` fuses the
    depth as matched, weight 1 per pixel; None: :attr:`filter_options`, by matcher, off for
    exact depth);
    ``min_weight`` the observation weight a mesh cube's corners need (None:
    DEFAULT_MIN_WEIGHT with the filter, 1.0 = one observation without)."""

    voxel: float = DEFAULT_VOXEL_M
    trunc: float | None = None
    roi: Roi | None = None
    method: str | None = None
    depth_source: str = "stereo"
    workers: int | None = None
    min_views: int = DEFAULT_MIN_VIEWS
    interpolation: str = "bilinear"
    score: bool = True
    seed: int = 0
    stereo_options: dict | None = None
    stereo: StereoOptions | None = None
    photometric: Any = True
    mount: Any = None
    depth_filter: DepthFilterOptions | None = None
    min_weight: float | None = None

    def __post_init__(self) -> None:
        if self.method is None:  # frozen: set once, here
            object.__setattr__(self, "method", getattr(self.stereo, "method", "birchfield"))

    @property
    def matcher(self) -> StereoOptions:
        """How each pair is matched; ConfigError for an unknown method, options of another
        method or both kinds of options."""
        return resolve_matcher(self.method, self.stereo, self.stereo_options, error=ConfigError)

    @property
    def trunc_m(self) -> float:
        return self.trunc if self.trunc is not None else TRUNC_VOXELS * self.voxel

    @property
    def filter_options(self) -> DepthFilterOptions:
        """``depth_filter``, or by default: off for exact depth (``depth_source`` truth: the
        plane fit only blurs its edges; realistic cell seeds 0-2, 0.16 -> 0.12 mm), else the
        matcher's default (:func:`default_filter`)."""
        if self.depth_filter is not None:
            return self.depth_filter
        if self.depth_source == "truth":
            return DepthFilterOptions(enabled=False)
        return default_filter(self.method)

    @property
    def mesh_min_weight(self) -> float:
        """The observation weight every corner of a meshed cube needs."""
        if self.min_weight is not None:
            return self.min_weight
        return DEFAULT_MIN_WEIGHT if self.filter_options.enabled else 1.0

    @property
    def behind_m(self) -> float:
        """How far behind an observed surface the TSDF is updated (m; at least a voxel)."""
        return max(self.voxel, BEHIND_TRUNC * self.trunc_m)


@dataclass(frozen=True)
class FusionProgress:
    """One step of :func:`fuse_recording`: ``stage`` is ``reconstruct`` or ``integrate``;
    ``done`` of ``total`` pairs; ``pair`` the pair's number; ``seconds`` it took."""

    stage: str
    pair: int
    done: int
    total: int
    seconds: float
    detail: str = ""


@dataclass
class PairDepth:
    """What one pair contributes: its depth frame (to fuse), up to RAW_POINTS_PER_PAIR of its
    raw base-frame points (a random, seeded subset: for the region of interest and to score
    the raw cloud), how many raw points it had, and its timings (s)."""

    pair: int
    left_view: int
    right_view: int
    timestamp_ns: int
    frame: DepthFrame
    raw_points: np.ndarray
    raw_point_count: int
    seconds: float
    views: tuple[ViewPose, ...] = ()
    timings_s: dict[str, float] = field(default_factory=dict)
    photometric: dict = field(default_factory=dict)  # what the correction did (report)


def fuse_recording(recording: str | Path, out_dir: str | Path,
                   options: FusionOptions = FusionOptions(), *, truth: SceneTruth | None = None,
                   progress: Callable[[FusionProgress], None] | None = None) -> dict:
    """Reconstruct and fuse every complete pair of ``recording`` into ``out_dir``; returns the
    report (also written as report.json).

    ``truth`` scores the model; by default it comes from the recording's metadata key
    ``scene_truth`` when present (``options.score=False`` skips scoring). Raises
    RecordingError for a recording without pairs, ConfigError for bad options or a region of
    interest no view sees.
    """
    _check_options(options)
    out = _output_dir(out_dir)
    timings: dict[str, float] = {}
    t_all = time.perf_counter()
    with _timed(timings, "read"):
        rec = Recording.open(recording)
        pairs = rec.require_pairs()
        truth = truth if truth is not None else _truth_from(rec)
    with _timed(timings, "reconstruct"):
        results, workers = reconstruct_pairs(recording, options, progress, recording=rec)
    with _timed(timings, "roi"):
        roi, roi_source = _region(options, results)
        check_roi_seen(roi, [r.frame for r in results])
    with _timed(timings, "filter"):
        results = [dataclasses.replace(r, frame=filter_frame(r.frame, options.filter_options))
                   for r in results]
    frames = [r.frame for r in results]
    volume = TsdfVolume(roi, options.voxel, options.trunc_m, interpolation=options.interpolation,
                        behind=options.behind_m)
    with _timed(timings, "integrate"):
        updated, integrate_s = _integrate(volume, results, progress)
    with _timed(timings, "extract"):
        mesh = extract_mesh(volume, options.mesh_min_weight)
    if len(mesh) == 0:
        raise ConfigError(f"no surface inside the region of interest {roi}: the views see it "
                          "but none of their depth lies in it; widen --roi")
    with _timed(timings, "support"):
        mesh, cloud, cloud_colors, support = fused_cloud(
            mesh, frames, SUPPORT_TOLERANCE_TRUNC * options.trunc_m, options.min_views)
    paths = {k: out / name for k, name in OUTPUT_NAMES.items()}
    report = _report(rec, options, roi, roi_source, volume, mesh, cloud, results,
                     zip(updated, integrate_s, support.per_frame, strict=True), workers)
    with _timed(timings, "write"):
        _write(paths, mesh, cloud, cloud_colors, results,
               {"source": str(recording), "pairs": str(len(results)),
                "voxel_m": repr(options.voxel), "roi_m": str(roi),
                "matcher": json.dumps(report["matcher"])})
    if truth is not None and options.score:
        with _timed(timings, "score"):
            report["accuracy"] = _score(truth, pairs, roi, mesh, cloud, results, options)
    timings["total"] = time.perf_counter() - t_all
    report["timings_s"] = {k: round(v, 3) for k, v in timings.items()}
    report["memory_mb"]["peak_rss"] = _peak_rss_mb(resource.RUSAGE_SELF)
    report["memory_mb"]["peak_rss_workers"] = _peak_rss_mb(resource.RUSAGE_CHILDREN)
    report["outputs"] = {k: str(p) for k, p in paths.items()}
    paths["report"].write_text(json.dumps(report, indent=2) + "\n")
    return report


def _integrate(volume: TsdfVolume, results: list[PairDepth], progress
               ) -> tuple[list[int], list[float]]:
    """Fuse every pair's depth; returns voxels updated and seconds, per pair."""
    updated, seconds = [], []
    for k, r in enumerate(results):
        t0 = time.perf_counter()
        updated.append(volume.integrate(r.frame))
        seconds.append(time.perf_counter() - t0)
        _say(progress, FusionProgress("integrate", r.pair, k + 1, len(results), seconds[-1],
                                      f"{updated[-1]} voxels updated"))
    return updated, seconds


def _write(paths: dict[str, Path], mesh, cloud: np.ndarray, cloud_colors: np.ndarray,
           results: list[PairDepth], metadata: dict[str, str]) -> None:
    """mesh.ply, fused.ply and fusion.mcap."""
    comment = f"armstereo fused from {len(results)} pairs, frame base, metres"
    write_mesh_ply(paths["mesh"], mesh, comment=comment)
    write_ply(paths["cloud"], cloud, cloud_colors, comment=comment)
    views = [v for r in results for v in r.views]
    write_fusion_mcap(paths["mcap"], mesh, cloud, cloud_colors, views, metadata)


def _check_options(o: FusionOptions) -> None:
    if not (math.isfinite(o.voxel) and 0 < o.voxel <= 0.1):
        raise ConfigError(f"--voxel must be in (0, 0.1] m, got {o.voxel}")
    if o.trunc is not None and not (math.isfinite(o.trunc) and o.voxel <= o.trunc <= 1.0):
        raise ConfigError(f"--trunc must be in [voxel = {o.voxel}, 1.0] m, got {o.trunc}")
    if o.depth_source not in DEPTH_SOURCES:
        raise ConfigError(f"depth source must be one of {', '.join(DEPTH_SOURCES)}, "
                          f"got {o.depth_source!r}")
    if o.workers is not None and o.workers < 1:
        raise ConfigError(f"workers must be >= 1, got {o.workers}")
    if o.min_views < 1:
        raise ConfigError(f"min_views must be >= 1, got {o.min_views}")
    if o.min_weight is not None and not (math.isfinite(o.min_weight) and o.min_weight > 0):
        raise ConfigError(f"min_weight must be > 0, got {o.min_weight}")
    if o.depth_filter is not None and not isinstance(o.depth_filter, DepthFilterOptions):
        raise ConfigError(f"depth_filter must be DepthFilterOptions, got {o.depth_filter!r}")
    o.matcher  # noqa: B018  (the matcher's options are checked as they are resolved)


def _output_dir(out_dir: str | Path) -> Path:
    out = Path(out_dir)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise ConfigError(f"cannot create output folder {out}: {err.strerror}") from None
    return out


def _truth_from(rec: Recording) -> SceneTruth | None:
    text = rec.metadata.get(METADATA_SCENE_TRUTH)
    return SceneTruth.from_json(text) if text else None


class _timed:
    """Context manager adding the block's wall time to ``timings[stage]``."""

    def __init__(self, timings: dict[str, float], stage: str):
        self.timings, self.stage = timings, stage

    def __enter__(self) -> None:
        self.t0 = time.perf_counter()

    def __exit__(self, *exc) -> None:
        self.timings[self.stage] = self.timings.get(self.stage, 0.0) + time.perf_counter() \
            - self.t0


def _say(progress, event: FusionProgress) -> None:
    if progress is not None:
        progress(event)


# ---------------------------------------------------------------------------- reconstruction
def default_workers(pairs: int) -> int:
    """Reconstruction processes: one per CORES_PER_WORKER available cores (the matcher already
    runs its rows on two threads), at most one per pair; 1 on a 2-core machine, where worker
    processes measured slower than one process (bench/fusion.py)."""
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    return max(1, min((cores or 1) // CORES_PER_WORKER, pairs))


def reconstruct_pairs(path: str | Path, o: FusionOptions = FusionOptions(),
                      progress: Callable[[FusionProgress], None] | None = None, *,
                      recording: Recording | None = None) -> tuple[list[PairDepth], int]:
    """Depth of every complete pair of the recording at ``path`` (``o.depth_source``, on
    ``o.workers`` processes), in pair order, and the number of processes used. ``recording``
    is the already opened file, if any."""
    path = Path(path)
    rec = recording if recording is not None else Recording.open(path)
    pairs = rec.require_pairs()
    if o.depth_source == "truth":
        results = []
        for k in range(len(pairs)):
            results.append(_pair_job(rec, k, o))
            _say(progress, FusionProgress("reconstruct", results[-1].pair, k + 1, len(pairs),
                                          results[-1].seconds, "ground truth"))
        return results, 1
    workers = o.workers or default_workers(len(pairs))
    if workers == 1:
        results = []
        for k in range(len(pairs)):
            results.append(_pair_job(rec, k, o))
            _report_pair(progress, results[-1], k + 1, len(pairs))
        return results, 1
    # spawn, not fork: the parent may hold OpenCV/numba threads whose locks a fork would copy.
    ctx = multiprocessing.get_context("spawn")
    results: list[PairDepth | None] = [None] * len(pairs)
    with ProcessPoolExecutor(workers, mp_context=ctx) as pool:
        futures = {pool.submit(_pair_job_in_worker, str(path), k, o): k
                   for k in range(len(pairs))}
        done = 0
        for fut in as_completed(futures):
            k = futures[fut]
            results[k] = fut.result()
            done += 1
            _report_pair(progress, results[k], done, len(pairs))
    return results, workers


def _report_pair(progress, r: PairDepth, done: int, total: int) -> None:
    _say(progress, FusionProgress("reconstruct", r.pair, done, total, r.seconds,
                                  f"{r.raw_point_count} points"))


_WORKER_RECORDINGS: dict[str, Recording] = {}


def _pair_job_in_worker(path: str, k: int, o: FusionOptions) -> PairDepth:
    """Reconstruct pair ``k`` in a worker process (the recording is opened once per worker;
    the matcher runs single-threaded there: the processes already share the cores)."""
    rec = _WORKER_RECORDINGS.get(path)
    if rec is None:
        rec = _WORKER_RECORDINGS[path] = Recording.open(path)
    return _pair_job(rec, k, o, threads=1)


def _pair_job(rec: Recording, k: int, o: FusionOptions, threads: int | None = None
              ) -> PairDepth:
    """Depth frame, raw points (a spread subset) and timings of the k-th complete pair."""
    from armstereo.reconstruct.pipeline import reconstruct_pair

    pair = rec.pairs[k]
    if o.mount is not None:
        pair = remounted(pair, o.mount)
    t0 = time.perf_counter()
    if o.depth_source == "truth":
        frame = frame_from_truth(pair)
        pts = frame_points(frame)
        timings: dict[str, float] = {}
        photometric: dict = {}
        left, right = pair.left, pair.right
    else:
        stereo = o.matcher
        if threads is not None and isinstance(stereo, BirchfieldOptions):
            stereo = dataclasses.replace(stereo, threads=threads)
        recon = reconstruct_pair(pair, stereo=stereo, photometric=_photometric(o, rec))
        frame = frame_from_reconstruction(recon)
        pts = recon.points_base
        timings = dict(recon.timings_s)
        photometric = recon.photometric
        left, right = ((pair.right, pair.left) if recon.swapped else (pair.left, pair.right))
    rng = np.random.default_rng(o.seed + k)
    keep = (rng.choice(len(pts), RAW_POINTS_PER_PAIR, replace=False)
            if len(pts) > RAW_POINTS_PER_PAIR else np.arange(len(pts)))
    views = tuple(ViewPose(v.index, pair.index, v.T_base_camera, v.intrinsics.K,
                           v.intrinsics.size, int(v.timestamp_ns)) for v in (pair.left, pair.right))
    return PairDepth(pair.index, left.index, right.index, int(left.timestamp_ns), frame,
                     np.asarray(pts, dtype=np.float32)[np.sort(keep)], len(pts),
                     time.perf_counter() - t0, views, timings, photometric)


# ---------------------------------------------------------------------------- roi, report
def _region(o: FusionOptions, results: list[PairDepth]) -> tuple[Roi, str]:
    if o.roi is not None:
        return o.roi, "given"
    roi = auto_roi([r.frame for r in results], [r.raw_points for r in results],
                   margin=o.trunc_m + 2 * o.voxel)
    return roi, "auto"


def _peak_rss_mb(who: int) -> float:
    return round(resource.getrusage(who).ru_maxrss / 1024.0, 1)  # Linux reports KiB


def _report(rec: Recording, o: FusionOptions, roi: Roi, roi_source: str, volume: TsdfVolume,
            mesh, cloud: np.ndarray, results: list[PairDepth], contributions, workers: int
            ) -> dict:
    """The report without timings, accuracy and outputs; ``contributions`` holds per pair
    (voxels updated, integration seconds, mesh vertices the pair sees)."""
    per_pair = [{"pair": r.pair, "left_view": r.left_view, "right_view": r.right_view,
                 "points": r.raw_point_count, "voxels_updated": int(u),
                 "mesh_vertices_seen": int(s), "reconstruct_s": round(r.seconds, 3),
                 "integrate_s": round(t, 3),
                 "exposure_gains": r.photometric.get("exposure", {}).get("gains")}
                for r, (u, t, s) in zip(results, contributions, strict=True)]
    return {
        "views": len(results), "voxel_m": o.voxel, "trunc_m": o.trunc_m,
        "behind_m": o.behind_m,
        "depth_filter": o.filter_options.record(), "mesh_min_weight": o.mesh_min_weight,
        "roi_m": roi.as_list(), "roi_source": roi_source, "depth_source": o.depth_source,
        "method": o.method if o.depth_source == "stereo" else None,
        "matcher": matcher_record(o.matcher) if o.depth_source == "stereo" else None,
        "workers": workers,
        "voxels": volume.voxel_count, "voxel_grid": list(volume.shape),
        "observed_voxels": int(np.count_nonzero(volume.weight)),
        "mesh": {"vertices": len(mesh.vertices), "faces": len(mesh), "area_m2": mesh.area()},
        "fused_points": len(cloud), "single_view_points": len(mesh.vertices) - len(cloud),
        "min_views": o.min_views,
        "photometric": _photometric_summary(o, rec, results),
        "memory_mb": {"tsdf": round(volume.memory_bytes / 2**20, 1)},
        "pairs": per_pair, "source": str(rec.path), "armstereo_version": __version__,
    }


def _photometric(o: FusionOptions, rec: Recording):
    """The photometric options of every pair: the vignetting of ``o.mount`` or else of the
    recording's mount file."""
    if o.mount is not None:
        return as_options(o.photometric).with_model(o.mount.vignetting)
    return for_recording(o.photometric, rec.metadata)


def _photometric_summary(o: FusionOptions, rec: Recording, results: list[PairDepth]) -> dict:
    """What the photometric correction did over the pairs (per pair gains are in ``pairs``)."""
    if o.depth_source != "stereo":
        return {"vignetting": {"applied": False}, "exposure": {"applied": False}}
    opts = _photometric(o, rec)
    first = next((r.photometric for r in results if r.photometric), {})
    applied = sum(bool(r.photometric.get("exposure", {}).get("applied")) for r in results)
    return {"vignetting": first.get("vignetting", {"applied": opts.removes_vignetting}),
            "exposure": {"requested": opts.exposure, "pairs_corrected": applied}}


def _score(truth: SceneTruth, pairs, roi: Roi, mesh, cloud: np.ndarray,
           results: list[PairDepth], o: FusionOptions) -> dict:
    """The accuracy block: the mesh against truth, plus the fused cloud and the raw pairs."""
    reference = reference_surface(pairs, roi)
    score = score_mesh(mesh, truth, reference).as_dict()
    raw = np.concatenate([r.raw_points for r in results])
    raw = raw[roi.contains(raw)]
    if len(raw) == 0:
        raise RecordingError("no raw stereo point inside the region of interest to score")
    score["raw_pairs"] = point_accuracy(raw, truth).as_dict()
    if len(cloud):
        score["fused_points"] = point_accuracy(cloud, truth).as_dict()
    return score
