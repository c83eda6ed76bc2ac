"""A 12-view mock scan and its fusion at 2 mm: time (target < 60 s in all), memory, accuracy.

Cases (each a fresh mock scan of the table scene with the UR5e and the default camera):

- ``tuning``: ring:12 at 55 deg elevation, radius 0.45 m, baseline 60 mm, camera noise 1 grey
  level, scene seed 0. The fusion defaults (bilinear depth lookup, truncation 4 voxels, two-view
  cloud rule) were chosen on this one.
- ``held-out`` (``--held-out``): sphere:12 from 45 deg, radius 0.5 m, camera noise 2, scene
  seed 7 (other textures), same defaults. (From 40 deg, as first measured, ``armstereo scan``
  refuses the tour: the lowest viewpoint, near the arm's base, is reachable only by a joint
  move through the shoulder singularity.)

For each: ``scan`` (plan + capture, simulated arm time is not waited for), ``fuse`` (the whole
``fuse_recording`` with scoring, default worker count) and the accuracy of the model, of the
raw pair clouds and, on the same recording, of the views' exact depth fused (the plumbing
check). ``--variants`` also fuses the same reconstructed depth with nearest-pixel lookup and
with truncation 3 and 6 voxels; ``--workers-ab`` times reconstruction of the 12 pairs in one
process against two worker processes, alternating, twice each; ``--open3d PYTHON`` fuses the
same depth frames with Open3D's VoxelBlockGrid in that interpreter (bench/open3d_peer.py) and
scores its mesh the same way. Writes Markdown (``--out``).

    .venv/bin/python -m bench.fusion [--held-out] [--variants] [--workers-ab]
                                     [--open3d /tmp/o3d/bin/python] [--out FILE.md]
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from armstereo import backends
from armstereo.apps.scan import ScanRequest, record_scan
from armstereo.evaluation.scene_truth import SceneTruth
from armstereo.fusion.frames import frame_from_truth
from armstereo.fusion.mesh import Mesh, extract_mesh
from armstereo.fusion.metrics import reference_surface, score_mesh
from armstereo.fusion.run import FusionOptions, fuse_recording, reconstruct_pairs
from armstereo.fusion.tsdf import Roi, TsdfVolume
from armstereo.mount import CameraMount
from armstereo.recording import Recording
from armstereo.robot.arm_model import ArmModel
from bench.harness import timed, write_report
from drivers.mock.scene import SCENE_CENTER, default_table_scene

TARGET = (SCENE_CENTER[0], SCENE_CENTER[1], 0.03)
CASES = {
    "tuning": {"views": "ring:12", "elevation_deg": 55.0, "radius": 0.45, "noise": 1.0,
               "scene_seed": 0},
    "held-out": {"views": "sphere:12", "elevation_deg": 45.0, "radius": 0.5, "noise": 2.0,
                 "scene_seed": 7},
}
BASELINE_M = 0.06
VOXEL_M = 0.002


def scan(path: Path, case: dict) -> tuple[float, int]:
    """Plan and record the case's scan with what ``armstereo scan`` runs; returns (seconds,
    pairs)."""
    def record():
        model = ArmModel.load("ur5e", mount=CameraMount.load(None))
        request = ScanRequest(target=TARGET, views=case["views"], radius=case["radius"],
                              elevation_deg=case["elevation_deg"], baseline=BASELINE_M)
        camera = backends.camera_config("mock", noise=case["noise"], seed=1,
                                        scene=default_table_scene(case["scene_seed"]))
        return record_scan(path, request, model, arm_config=backends.arm_config("mock", seed=1),
                           camera_config=camera, progress=None)

    outcome, seconds = timed(record)
    return seconds, len(outcome.result.pairs)


def _acc(report: dict) -> dict:
    a = report["accuracy"]
    return {"acc": a["accuracy_mean_mm"], "comp": a["completeness_mean_mm"],
            "w2": a["within_2mm"], "c2": a["completeness_within_2mm"],
            "c5": a["completeness_within_5mm"], "f1_2": a["f1_2mm"],
            "cov": a["visible_surface_covered"], "raw": a["raw_pairs"]["accuracy_mean_mm"],
            "cloud": a.get("fused_points", {}).get("accuracy_mean_mm", float("nan"))}


def run_case(name: str, case: dict, tmp: Path, lines: list[str]) -> dict:
    path = tmp / f"{name}.mcap"
    c0 = time.process_time()
    scan_s, pairs = scan(path, case)
    print(f"{name}: scan {scan_s:.1f} s ({pairs} pairs)", file=sys.stderr)
    report, fuse_s = timed(fuse_recording, path, tmp / f"{name}_out",
                           FusionOptions(voxel=VOXEL_M))
    cpu_s = time.process_time() - c0  # all threads of this process: load-independent
    truth = fuse_recording(path, tmp / f"{name}_truth",
                           FusionOptions(voxel=VOXEL_M, depth_source="truth", workers=1))
    a, t = _acc(report), report["timings_s"]
    at = _acc(truth)
    mem = report["memory_mb"]
    lines += [
        f"### {name}: {case['views']}, elevation {case['elevation_deg']:g} deg, radius "
        f"{case['radius']} m, camera noise {case['noise']:g}, scene seed {case['scene_seed']}",
        "",
        f"- scan (plan + mock capture of {pairs} pairs): **{scan_s:.1f} s**; fuse (reconstruct, "
        f"fuse, write, score): **{fuse_s:.1f} s**; in all **{scan_s + fuse_s:.1f} s** wall, "
        f"{cpu_s:.1f} s of CPU (both threads; a quiet 2-core machine takes at most this long)",
        "- fuse stages (s): " + ", ".join(f"{k} {v:.2f}" for k, v in t.items()),
        f"- grid {report['voxel_grid']} = {report['voxels'] / 1e6:.1f} M voxels, TSDF "
        f"{mem['tsdf']:.0f} MB; peak RSS {mem['peak_rss']:.0f} MB (this process, all cases so "
        f"far), workers {report['workers']}",
        f"- mesh {report['mesh']['faces']} triangles, fused cloud {report['fused_points']} "
        f"points ({report['single_view_points']} single-pair vertices left out)",
        "",
        "| depth fused | accuracy mm | completeness mm | acc. within 2 mm | comp. within 2 mm "
        "| comp. within 5 mm | F1 @ 2 mm | visible surface covered | raw pairs mm "
        "| fused cloud mm |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for label, x in (("stereo (Birchfield-Tomasi)", a), ("exact (ground truth)", at)):
        lines.append(f"| {label} | {x['acc']:.3f} | {x['comp']:.3f} | {x['w2'] * 100:.1f} % | "
                     f"{x['c2'] * 100:.1f} % | {x['c5'] * 100:.1f} % | {x['f1_2']:.3f} | "
                     f"{x['cov'] * 100:.1f} % | {x['raw']:.3f} | {x['cloud']:.3f} |")
    lines.append("")
    return {"path": path, "report": report}


def variants(path: Path, report: dict, lines: list[str]) -> None:
    """Fuse the same reconstructed depth with other lookups and truncations."""
    results, _ = reconstruct_pairs(path, FusionOptions(workers=1))
    rec = Recording.open(path)
    truth = SceneTruth.from_json(rec.metadata["scene_truth"])
    roi = Roi.parse(",".join(str(v) for v in report["roi_m"]))
    reference = reference_surface(rec.pairs, roi)
    lines += ["| lookup | truncation | accuracy mm | completeness mm | comp. within 2 mm | "
              "integrate s |", "|---|---|---|---|---|---|"]
    for interp, trunc_vox in (("bilinear", 4), ("nearest", 4), ("bilinear", 3),
                              ("bilinear", 6)):
        volume = TsdfVolume(roi, VOXEL_M, trunc_vox * VOXEL_M, interpolation=interp)
        t0 = time.perf_counter()
        for r in results:
            volume.integrate(r.frame)
        dt = time.perf_counter() - t0
        s = score_mesh(extract_mesh(volume), truth, reference)
        lines.append(f"| {interp} | {trunc_vox} voxels | {s.accuracy_mean_mm:.3f} | "
                     f"{s.completeness_mean_mm:.3f} | {s.completeness_within_2mm * 100:.1f} % | "
                     f"{dt:.2f} |")
    lines.append("")


def open3d_peer(python: str, path: Path, report: dict, tmp: Path, lines: list[str]) -> None:
    """Our fusion and Open3D's on the same frames (stereo and exact), same scoring."""
    rec = Recording.open(path)
    truth = SceneTruth.from_json(rec.metadata["scene_truth"])
    roi = Roi.parse(",".join(str(v) for v in report["roi_m"]))
    reference = reference_surface(rec.pairs, roi)
    trunc = 4 * VOXEL_M
    stereo = [r.frame for r in reconstruct_pairs(path, FusionOptions(workers=1))[0]]
    exact = [frame_from_truth(p) for p in rec.pairs]
    lines += ["| depth | fusion | accuracy mm | completeness mm | comp. within 2 mm | "
              "integrate s (12 frames) | extract s |", "|---|---|---|---|---|---|---|"]
    for label, frames in (("stereo", stereo), ("exact", exact)):
        volume = TsdfVolume(roi, VOXEL_M, trunc)
        t0 = time.perf_counter()
        for f in frames:
            volume.integrate(f)
        t_int = time.perf_counter() - t0
        t0 = time.perf_counter()
        mesh = extract_mesh(volume)
        t_ext = time.perf_counter() - t0
        _row(lines, label, "armstereo (numba + scikit-image)", score_mesh(mesh, truth, reference),
             t_int, t_ext)
        npz = tmp / f"frames_{label}.npz"
        _save_frames(npz, frames, roi, trunc)
        flags = [[], ["--weight-threshold", "1.0"]]
        if label == "exact":
            flags.append(["--no-half-pixel"])
        for flag in flags:
            out = tmp / f"o3d_{label}.npz"
            subprocess.run([python, str(Path(__file__).with_name("open3d_peer.py")), str(npz),
                            str(out), *flag], check=True)
            got = np.load(out)
            o3d_mesh = Mesh(got["vertices"], got["faces"],
                            np.zeros(got["vertices"].shape, np.uint8))
            name = "Open3D 0.20 VoxelBlockGrid, " + {
                0: "cx/cy + 0.5, weight > 0.5", 2: "cx/cy + 0.5, weight > 1.0",
                1: "cx/cy as given, weight > 0.5"}[len(flag) if flag != ["--no-half-pixel"]
                                                   else 1]
            _row(lines, label, name, score_mesh(o3d_mesh, truth, reference),
                 float(got["integrate_s"]), float(got["extract_s"]))
    lines.append("")


def _row(lines, label, name, s, t_int, t_ext) -> None:
    lines.append(f"| {label} | {name} | {s.accuracy_mean_mm:.3f} | {s.completeness_mean_mm:.3f} "
                 f"| {s.completeness_within_2mm * 100:.1f} % | {t_int:.2f} | {t_ext:.2f} |")


def _save_frames(npz: Path, frames, roi: Roi, trunc: float) -> None:
    """Frames for the peer, depth limited to the ROI (grown by the truncation) so that Open3D,
    which allocates blocks wherever depth lands, works on the same region."""
    lo, hi = np.subtract(roi.lo, trunc), np.add(roi.hi, trunc)
    data = {"count": len(frames), "voxel": VOXEL_M, "trunc": trunc,
            "roi": np.array(roi.as_list())}
    for k, f in enumerate(frames):
        h, w = f.depth.shape
        v, u = np.mgrid[0:h, 0:w]
        z = f.depth.astype(np.float64)
        cam = np.stack([(u - f.K[0, 2]) / f.K[0, 0] * z, (v - f.K[1, 2]) / f.K[1, 1] * z, z], -1)
        p = cam @ f.T_base_camera[:3, :3].T + f.T_base_camera[:3, 3]
        inside = np.all((p >= lo) & (p <= hi), axis=-1)
        data[f"depth_{k}"] = np.where(inside, f.depth, np.nan).astype(np.float32)
        data[f"K_{k}"], data[f"T_{k}"] = f.K, f.T_base_camera
    np.savez(npz, **data)


def workers_ab(path: Path, lines: list[str]) -> None:
    times: dict[int, list[float]] = {1: [], 2: []}
    for _ in range(2):
        for w in (1, 2):
            t0 = time.perf_counter()
            reconstruct_pairs(path, FusionOptions(workers=w))
            times[w].append(time.perf_counter() - t0)
    lines += ["| reconstruction of 12 pairs | runs (s) | median (s) |", "|---|---|---|"]
    for w, ts in times.items():
        label = "one process (matcher on 2 threads)" if w == 1 else \
            "2 worker processes (matcher on 1 thread each, spawn)"
        lines.append(f"| {label} | {', '.join(f'{t:.1f}' for t in ts)} | "
                     f"{statistics.median(ts):.1f} |")
    lines.append("")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--held-out", action="store_true", help="also run the held-out case")
    ap.add_argument("--variants", action="store_true", help="lookup/truncation variants")
    ap.add_argument("--workers-ab", action="store_true", help="1 process vs 2 workers")
    ap.add_argument("--open3d", default=None, metavar="PYTHON",
                    help="an interpreter with open3d: run bench/open3d_peer.py as the peer")
    ap.add_argument("--out", default=None, help="write the Markdown here too")
    args = ap.parse_args()
    lines = ["# Fusion benchmark: 12-view mock scan, 2 mm voxels", "",
             f"Command: `.venv/bin/python -m bench.fusion {' '.join(sys.argv[1:])}`  ",
             f"Date: {time.strftime('%Y-%m-%d')}; 2 cores shared with other work (timings "
             "rough: compare rows of one run).", ""]
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        first = run_case("tuning", CASES["tuning"], tmp, lines)
        if args.held_out:
            run_case("held-out", CASES["held-out"], tmp, lines)
        if args.variants:
            lines += ["### Depth lookup and truncation (tuning scan, same stereo depth)", ""]
            variants(first["path"], first["report"], lines)
        if args.open3d:
            lines += ["### Open3D's TSDF on the same frames (tuning scan)", ""]
            open3d_peer(args.open3d, first["path"], first["report"], tmp, lines)
        if args.workers_ab:
            lines += ["### Worker processes for reconstruction (tuning scan)", ""]
            workers_ab(first["path"], lines)
    text = "\n".join(lines) + "\n"
    write_report(text, args.out)


if __name__ == "__main__":
    main()
