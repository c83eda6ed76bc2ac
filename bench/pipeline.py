"""Time pair -> point cloud per stage on a 640x480 synthetic pair (target: < 0.5 s in total).

Renders the mock table scene (drivers.mock.scene) from two poses 0.55 m above the table,
writes them to a temporary recording exactly as a capture would, then runs the pipeline on the
recording's pair ``--repeat`` times (a fresh ``Recording.open`` each time so PNG decoding is
counted) and prints the median of each stage: decode, rectify, match, triangulate, write (PLY).
The first run also compiles the matcher (numba cache) and is reported separately.

    .venv/bin/python -m bench.pipeline [--repeat 7] [--method birchfield|sgbm] [--baseline 0.06]
"""

from __future__ import annotations

import argparse
import math
import statistics
import sys
import tempfile
from pathlib import Path

import numpy as np

from armstereo.devices import Frame
from armstereo.io.ply import write_ply
from armstereo.mount import CameraMount
from armstereo.reconstruct.outputs import write_outputs
from armstereo.reconstruct.pipeline import reconstruct_pair
from armstereo.recording import Recording, RecordingWriter
from armstereo.transforms import invert, make_T, rot_x, rot_z
from bench.harness import timed
from drivers.mock.scene import SCENE_CENTER, default_table_scene

STAGES = ("decode", "rectify", "match", "triangulate", "write")
HEIGHT_M = 0.55


def make_recording(path: Path, baseline: float, direction: str) -> None:
    """Two views of the default table scene, the second moved along camera x or y."""
    mount = CameraMount.load()
    scene = default_table_scene()
    T0 = make_T(rot_x(math.pi) @ rot_z(0.05), [SCENE_CENTER[0], SCENE_CENTER[1], HEIGHT_M])
    step = {"x": [baseline, 0, 0], "y": [0, baseline, 0], "xy": [baseline / math.sqrt(2)] * 2
            + [0]}[direction]
    T1 = T0.copy()
    T1[:3, 3] += T0[:3, :3] @ np.array(step, dtype=float)
    with RecordingWriter(path, metadata={"robot": "bench"}) as w:
        w.write_calibration(mount.intrinsics, 1)
        for k, T in enumerate((T0, T1)):
            img, depth = scene.render(T, mount.intrinsics)
            w.write_view(k, Frame(img, 10 + k, depth), np.zeros(6), [f"j{i}" for i in range(6)],
                         T @ invert(mount.T_flange_camera), mount.T_flange_camera, settle_s=0.0)
        w.write_pair(0, 0, 1, baseline, baseline, direction)


def run_once(rec_path: Path, out: Path, method: str) -> tuple[dict[str, float], object]:
    pair, t_open = timed(lambda: Recording.open(rec_path)[0])
    recon = reconstruct_pair(pair, method=method)
    recon.timings_s["decode"] += t_open  # reading the file is part of getting the images
    _, recon.timings_s["write"] = timed(write_ply, out / "bench.ply", recon.points_base,
                                        recon.colors_bgr)
    return recon.timings_s, recon


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=7)
    ap.add_argument("--method", default="birchfield", choices=("birchfield", "sgbm"))
    ap.add_argument("--baseline", type=float, default=0.06, help="metres (default 0.06)")
    ap.add_argument("--direction", default="x", choices=("x", "y", "xy"))
    ap.add_argument("--keep", type=Path, default=None,
                    help="also write all outputs (PLY, PNGs, MCAP) of the last run here")
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        rec_path = tmp / "bench.mcap"
        make_recording(rec_path, args.baseline, args.direction)
        first, _ = run_once(rec_path, tmp, args.method)
        runs = [run_once(rec_path, tmp, args.method) for _ in range(args.repeat)]
        recon = runs[-1][1]
        if args.keep:
            write_outputs(recon, args.keep, "bench")
    med = {k: statistics.median(r[0][k] for r in runs) for k in STAGES}
    total = statistics.median(sum(r[0][k] for k in STAGES) for r in runs)
    ok = np.isfinite(recon.depth_original) & np.isfinite(recon.depth_truth)
    rel = np.abs(recon.depth_original[ok] / recon.depth_truth[ok] - 1)
    print(f"pair 640x480 -> {len(recon.points_base)} points, method {args.method}, baseline "
          f"{args.baseline * 1000:.0f} mm along {args.direction}, canvas "
          f"{recon.rectified.size[0]}x{recon.rectified.size[1]}, disparities "
          f"0..{recon.window.max_disparity} "
          f"(depth {recon.window.near:.3f}..{recon.window.far:.3f} m)")
    density = ok.sum() / np.isfinite(recon.depth_truth).sum()
    print(f"depth vs truth: median rel. error {np.median(rel):.4f}, within 1 %: "
          f"{np.mean(rel < 0.01):.1%}, density {density:.1%}")
    print(f"first run (includes numba load/compile): {sum(first[k] for k in STAGES):.3f} s")
    print(f"median of {args.repeat} runs:")
    for k in STAGES:
        print(f"  {k:<12} {med[k] * 1000:7.1f} ms")
    print(f"  {'total':<12} {total * 1000:7.1f} ms  (target < 500 ms)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
