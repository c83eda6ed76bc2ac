"""Greedy next-best view (``--views auto:N``) against fixed layouts with the same budget.

Each scan of the mock table scene (UR5e, default camera, 1 grey level of noise, radius 0.45 m,
elevation 55 deg, baseline 60 mm) is recorded by ``record_scan`` (what ``armstereo scan``
runs) and fused at 2 mm twice: with stereo depth (the product) and with the views' exact depth
(what the chosen views can see at best). Completeness is measured against ONE reference for
all scans: the true surface visible from a dense scan (``sphere:24``, the candidates auto:N
chooses from, for N <= 8), inside a fixed region of interest around the scene, so a layout
that leaves a side unseen is charged for it (``fuse``'s own report measures each scan against
what its own views see).

    .venv/bin/python -m bench.nbv [--budgets 4 6] [--seed 1] [--out FILE.md]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from armstereo import backends
from armstereo.apps.scan import ScanRequest, record_scan
from armstereo.evaluation.scene_truth import SceneTruth
from armstereo.fusion.mesh_ply import read_mesh_ply
from armstereo.fusion.metrics import reference_surface, score_mesh
from armstereo.fusion.run import FusionOptions, fuse_recording
from armstereo.fusion.tsdf import Roi
from armstereo.mount import CameraMount
from armstereo.recording import Recording
from armstereo.robot.arm_model import ArmModel
from bench.harness import timed, write_report

TARGET = (-0.45, -0.13, 0.03)
ROI = Roi((-0.65, -0.33, -0.012), (-0.25, 0.07, 0.17))  # the scene's objects and table around
DENSE = "sphere:24"


def scan(path: Path, views: str, seed: int) -> tuple[float, object]:
    model = ArmModel.load("ur5e", mount=CameraMount.load(None))
    request = ScanRequest(target=TARGET, views=views, radius=0.45, elevation_deg=55.0,
                          baseline=0.06)
    outcome, seconds = timed(
        record_scan, path, request, model, arm_config=backends.arm_config("mock", seed=seed),
        camera_config=backends.camera_config("mock", noise=1.0, seed=seed), progress=None)
    return seconds, outcome


def score(path: Path, out: Path, depth: str, truth: SceneTruth, reference) -> dict:
    fuse_recording(path, out, FusionOptions(voxel=0.002, roi=ROI, depth_source=depth,
                                            workers=1, score=False))
    s = score_mesh(read_mesh_ply(out / "mesh.ply"), truth, reference)
    return {"acc": s.accuracy_mean_mm, "comp": s.completeness_mean_mm,
            "c2": s.completeness_within_2mm, "c5": s.completeness_within_5mm,
            "cov": s.visible_surface_covered}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--budgets", type=int, nargs="+", default=[4, 6])
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--out", default=None)
    args = ap.parse_args()
    lines = ["# Next-best view vs fixed layouts (mock table scene)", "",
             f"Command: `.venv/bin/python -m bench.nbv {' '.join(sys.argv[1:])}`  ",
             f"Date: {time.strftime('%Y-%m-%d')}; reference surface: the true surface visible "
             f"from {DENSE} (the auto candidates), inside {ROI}.", "",
             "| layout | pairs | viewpoints | scan s | exact depth: comp. mm | within 2 mm | "
             "within 5 mm | surface covered | stereo: acc. mm | comp. mm | within 5 mm | "
             "surface covered |", "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        _, _ = scan(tmp / "dense.mcap", DENSE, args.seed)
        dense = Recording.open(tmp / "dense.mcap")
        truth = SceneTruth.from_json(dense.metadata["scene_truth"])
        reference = reference_surface(dense.pairs, ROI)
        for n in args.budgets:
            for views in (f"auto:{n}", f"ring:{n}", f"sphere:{n}"):
                path = tmp / f"{views.replace(':', '_')}.mcap"
                secs, outcome = scan(path, views, args.seed)
                chosen = [p.viewpoint for p in outcome.result.pairs]
                exact = score(path, tmp / f"{path.stem}_exact", "truth", truth, reference)
                stereo = score(path, tmp / f"{path.stem}_stereo", "stereo", truth, reference)
                print(views, chosen, exact, stereo, file=sys.stderr, flush=True)
                lines.append(
                    f"| {views} | {len(chosen)} | {', '.join(map(str, chosen))} | {secs:.1f} | "
                    f"{exact['comp']:.2f} | {exact['c2'] * 100:.1f} % | "
                    f"{exact['c5'] * 100:.1f} % | {exact['cov'] * 100:.1f} % | "
                    f"{stereo['acc']:.3f} | {stereo['comp']:.2f} | {stereo['c5'] * 100:.1f} % | "
                    f"{stereo['cov'] * 100:.1f} % |")
    text = "\n".join(lines) + "\n"
    write_report(text, args.out)


if __name__ == "__main__":
    np.seterr(all="ignore")
    main()
