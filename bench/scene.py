"""Time scene analysis on a ~300k-point tabletop cloud (target: < 1 s), with scikit-learn's
DBSCAN beside our voxel clustering on the same points.

Clouds: ``synthetic`` (default), an orthographic scan of the mock table scene's exact
primitives with 0.3 mm height noise and a few mismatch fragments, sized to ``--points``; or any
PLY/MCAP given with ``--cloud`` (e.g. the demo's ``points.ply``, real stereo). Each run
analyses the cloud ``--repeat`` times and prints the median per stage, then clusters the points
above the plane with :func:`armstereo.scene.cluster.voxel_clusters` and with
``sklearn.cluster.DBSCAN`` (eps = the voxel edge, min_samples 10, one job) and reports their
times, cluster counts and agreement (adjusted Rand index on the points both call non-noise).
Wall times on a shared machine swing with its load; the process's CPU time swings less.

    .venv/bin/python -m bench.scene [--points 300000] [--repeat 5] [--cloud FILE] [--markdown]
"""

from __future__ import annotations

import argparse
import math
import statistics
import sys
import time

import numpy as np

from armstereo.scene import SceneCloud, SceneOptions, analyze_scene, load_cloud
from armstereo.scene.cluster import NOISE, voxel_clusters
from armstereo.scene.synthetic import scan
from bench.harness import best_time
from drivers.mock.scene import SCENE_CENTER, default_table_scene

EXTENT = (0.25, 0.22)  # half extents of the scanned table area around the scene centre (m)


def synthetic_cloud(points: int, seed: int = 0) -> SceneCloud:
    """The mock table scene scanned from above with about ``points`` points."""
    truth = default_table_scene(seed).truth()
    area = 4 * EXTENT[0] * EXTENT[1]
    spacing = math.sqrt(area / points)
    shifted = [type(p)(p.name, p.kind, _shift(p.T_base_local), p.dims) for p in truth.primitives]
    cloud = scan(type(truth)(shifted, truth.support), spacing=spacing, noise=0.0003, seed=seed,
                 extent=EXTENT)
    rng = np.random.default_rng(seed)
    frags = rng.uniform((-0.2, -0.2, 0.01), (0.2, 0.2, 0.12), (40, 3))
    blobs = np.vstack([f + rng.normal(0, 0.002, (30, 3)) for f in frags])
    pts = np.vstack([cloud.points, blobs])
    colors = np.vstack([cloud.colors_bgr, np.full((len(blobs), 3), 128, np.uint8)])
    return SceneCloud(pts, colors, "base", f"synthetic {len(pts)} points")


def _shift(T: np.ndarray) -> np.ndarray:
    """Move the scene so that SCENE_CENTER sits at the origin (the scan is centred there)."""
    T = T.copy()
    T[:2, 3] -= SCENE_CENTER
    return T


def time_analysis(cloud: SceneCloud, repeat: int) -> dict[str, float]:
    runs = []
    for _ in range(repeat):
        t0, c0 = time.perf_counter(), time.process_time()
        analysis = analyze_scene(cloud)
        runs.append({**analysis.timings_s, "total": time.perf_counter() - t0,
                     "total CPU (this process)": time.process_time() - c0})
    return {k: statistics.median(r[k] for r in runs) for k in runs[0]}, analysis


def compare_clustering(cloud: SceneCloud, analysis, repeat: int) -> list[tuple]:
    from sklearn.cluster import DBSCAN
    from sklearn.metrics import adjusted_rand_score

    opts = SceneOptions()
    h = analysis.plane.heights(cloud.points)
    pts = analysis.plane.to_plane(cloud.points[(h > opts.plane_threshold_m)
                                               & (h <= opts.max_height_m)])
    rows = []
    t_ours = best_time(lambda: voxel_clusters(pts, opts.cluster_voxel_m,
                                          min_voxel_points=opts.min_voxel_points,
                                          min_cluster_points=opts.min_points), repeat)
    ours = voxel_clusters(pts, opts.cluster_voxel_m, min_voxel_points=opts.min_voxel_points,
                          min_cluster_points=opts.min_points)
    dbscan = DBSCAN(eps=opts.cluster_voxel_m, min_samples=10, n_jobs=1)
    t_ref = best_time(lambda: dbscan.fit_predict(pts), max(1, repeat // 2))
    ref = dbscan.fit_predict(pts)
    ref = _drop_small(ref, opts.min_points)
    both = (ours != NOISE) & (ref != NOISE)
    ari = adjusted_rand_score(ref[both], ours[both]) if both.any() else float("nan")
    rows.append(("voxel components (ours)", len(pts), t_ours, _count(ours),
                 float(np.mean(ours == NOISE)), ari))
    rows.append(("sklearn DBSCAN", len(pts), t_ref, _count(ref), float(np.mean(ref == NOISE)),
                 1.0))
    return rows


def _drop_small(labels: np.ndarray, min_points: int) -> np.ndarray:
    out = labels.copy()
    ids, counts = np.unique(labels[labels >= 0], return_counts=True)
    out[np.isin(labels, ids[counts < min_points])] = NOISE
    return out


def _count(labels: np.ndarray) -> int:
    return len(set(labels.tolist()) - {NOISE})




def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--points", type=int, default=300_000)
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--cloud", default=None, help="PLY or MCAP to use instead of a synthetic one")
    ap.add_argument("--markdown", action="store_true", help="print Markdown tables")
    args = ap.parse_args()
    cloud = load_cloud(args.cloud) if args.cloud else synthetic_cloud(args.points)
    stages, analysis = time_analysis(cloud, args.repeat)
    print(f"cloud: {cloud.source} ({len(cloud.points):,} points), {len(analysis.objects)} "
          f"objects, {analysis.rejected_clusters} rejected clusters; median of {args.repeat}")
    print("\n| stage | time (ms) |\n|---|---|" if args.markdown else "")
    for k, v in stages.items():
        print(f"| {k} | {v * 1000:.0f} |" if args.markdown else f"  {k:<12} {v * 1000:7.0f} ms")
    rows = compare_clustering(cloud, analysis, args.repeat)
    if args.markdown:
        print("\n| clustering | points | time (ms) | clusters >= min_points | noise share | "
              "ARI vs DBSCAN |\n|---|---|---|---|---|---|")
    for name, n, t, k, noise, ari in rows:
        if args.markdown:
            print(f"| {name} | {n:,} | {t * 1000:.0f} | {k} | {noise:.2%} | {ari:.4f} |")
        else:
            print(f"  {name:<24} {n:,} pts  {t * 1000:7.0f} ms  {k} clusters  noise "
                  f"{noise:.2%}  ARI {ari:.4f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
