"""LMedS robustness: share of the true inliers kept, worst of 10 trials, 30 % gross outliers.

The study's synthetic two-view data (armstereo.epipolar.study_scenes: cube and cloud scenes,
lateral, forward and general motions), 100 points per trial, 0.5 px noise, 30 % of the
matches replaced by uniform outliers, 10 trials per cell, seeded like `armstereo study
epipolar`. Per cell: the smallest (and mean) share of the true inliers inside each estimator's
mask. Side by side, in the same run:

- `lmeds` (now): estimate_fundamental(..., "lmeds"), mask = Sampson distance < 1 px;
- `lmeds before`: what `lmeds` was before (OpenCV's LMedS plus an 8-point refit on its
  inliers), same 1 px mask;
- `OpenCV mask`: cv2.findFundamentalMat(FM_LMEDS) with the mask OpenCV returns (its own
  threshold, 2.5 robust sigmas: about 2 px here, so it also keeps more outliers);
- `OpenCV F @1px`: OpenCV's LMedS matrix with our 1 px mask.

Seed 0 is the data the polish was chosen on; seeds 1 and 2 were not looked at (held out).

    .venv/bin/python -m bench.lmeds [--out bench/results/lmeds.md]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import cv2
import numpy as np

from armstereo.epipolar.fundamental import estimate_fundamental
from armstereo.epipolar.linear import opencv_fundamental, refit_on_inliers
from armstereo.epipolar.metrics import sampson_distance
from armstereo.epipolar.study_scenes import IMAGE_SIZE, MOTIONS, SCENES, two_views
from bench.harness import command_line, machine_note, timed, write_report

NOISE_PX, OUTLIERS, TRIALS, POINTS, THRESHOLD = 0.5, 0.3, 10, 100, 1.0
ESTIMATORS = ("lmeds", "lmeds before", "OpenCV mask", "OpenCV F @1px")


def trials(seed: int, scene: str, motion: str):
    rng = np.random.default_rng([seed, SCENES.index(scene), MOTIONS.index(motion),
                                 int(NOISE_PX * 1000)])
    for _ in range(TRIALS):
        v = two_views(scene, motion, POINTS, rng)
        x1 = v.x1 + rng.normal(0.0, NOISE_PX, v.x1.shape)
        x2 = v.x2 + rng.normal(0.0, NOISE_PX, v.x2.shape)
        bad = rng.random(len(x2)) < OUTLIERS
        x2[bad] = rng.uniform((0, 0), IMAGE_SIZE, (int(bad.sum()), 2))
        yield x1, x2, ~bad


def masks(x1, x2, trial: int) -> dict[str, tuple[np.ndarray, float]]:
    out = {}
    (_, m), dt = timed(estimate_fundamental, x1, x2, "lmeds", seed=trial, allow_degenerate=True)
    out["lmeds"] = (m, dt)
    start = (x1, x2, "lmeds", THRESHOLD, 0.999, 5000)
    F, dt = timed(lambda: refit_on_inliers(opencv_fundamental(*start), x1, x2, THRESHOLD))
    out["lmeds before"] = (sampson_distance(F, x1, x2) < THRESHOLD, dt)
    (Fc, mc), dt = timed(cv2.findFundamentalMat, x1, x2, cv2.FM_LMEDS, THRESHOLD, 0.999, 5000)
    out["OpenCV mask"] = (mc.ravel().astype(bool), dt)
    out["OpenCV F @1px"] = (sampson_distance(Fc[:3], x1, x2) < THRESHOLD, dt)
    return out


def table(seed: int) -> tuple[list[str], dict[str, float]]:
    lines = ["| scene | motion | " + " | ".join(f"{e}: worst / mean (outliers kept)"
                                                for e in ESTIMATORS) + " |",
             "|---|---|" + "---|" * len(ESTIMATORS)]
    worst = {e: 1.0 for e in ESTIMATORS}
    times = {e: [] for e in ESTIMATORS}
    for scene in SCENES:
        for motion in MOTIONS[1:]:  # rotation only has no epipolar geometry
            kept = {e: [] for e in ESTIMATORS}
            outl = {e: [] for e in ESTIMATORS}
            for k, (x1, x2, inl) in enumerate(trials(seed, scene, motion)):
                for e, (m, dt) in masks(x1, x2, k).items():
                    kept[e].append(m[inl].mean())
                    outl[e].append(m[~inl].mean())
                    times[e].append(dt)
            cells = []
            for e in ESTIMATORS:
                worst[e] = min(worst[e], min(kept[e]))
                cells.append(f"{min(kept[e]) * 100:.1f} % / {np.mean(kept[e]) * 100:.1f} % "
                             f"({np.mean(outl[e]) * 100:.1f} %)")
            lines.append(f"| {scene} | {motion} | " + " | ".join(cells) + " |")
    lines += ["", "Worst over all cells: " + ", ".join(f"{e} {worst[e] * 100:.1f} %"
                                                       for e in ESTIMATORS) + ".",
              "Median time per call: " + ", ".join(
                  f"{e} {np.median(times[e]) * 1000:.1f} ms" for e in ESTIMATORS[:3]) + "."]
    return lines, worst


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=None)
    args = ap.parse_args(argv)
    lines = ["# LMedS robustness (bench.lmeds)", "",
             f"{POINTS} points, {NOISE_PX} px noise, {OUTLIERS:.0%} gross outliers, {TRIALS} "
             f"trials per cell, mask threshold {THRESHOLD} px (Sampson) unless noted; cells: "
             "smallest / mean share of the true inliers kept (mean share of the outliers "
             "kept). Target (issue 25): at least 85 % in the worst trial.", ""]
    for seed, title in ((0, "Tuning data (seed 0)"), (1, "Held out (seed 1)"),
                        (2, "Held out (seed 2)")):
        part, _ = table(seed)
        lines += [f"## {title}", ""] + part + [""]
    lines += [f"`{command_line('bench.lmeds', argv)}`; {machine_note()}"]
    write_report("\n".join(lines) + "\n", args.out)


if __name__ == "__main__":
    main()
