"""The demo's error budget: the depth error each error source of the realistic mock causes alone,
and what is left after each correction, measured by switching the sources on one at a time.

Every row is a full demo run (``armstereo.apps.demo.run_demo``: capture through the mock arm and
camera, reconstruct, score against the mock's exact ground truth) on the realistic profile's
desk scene at the demo's 80 mm baseline, with only the named error sources on. Rows:

- ``none``: every source off (what the desk scene and the matcher give on their own);
- one row per source alone: the arm's factory calibration with the NOMINAL model used,
  hand-eye error, intrinsics error, image effects, joint noise (encoder noise and ringing);
- the image effects one at a time (noise, blur, vignetting, exposure and white balance);
- all sources, nothing corrected (nominal model);
- after reading the controller's calibrated kinematics (the demo's default);
- after a perfect camera calibration (the software is handed the camera's true intrinsics and
  hand-eye transform; armstereo has no calibration command yet, so this is the bound it can
  reach).

Scores: median |relative depth error| on the pixels both views see, density, and the median
distance of the reconstructed points (base frame) to the true surfaces. Each row is run with
several seeds (each seed draws another arm calibration, camera error and scene texture offset)
and both matchers (Birchfield-Tomasi and StereoSGBM); the table gives the median over the seeds
and, in brackets, the range.

    .venv/bin/python -m bench.error_budget [--seeds 0 1 2] [--methods birchfield sgbm]
        [--out bench/results/error_budget.md]
"""

from __future__ import annotations

import argparse
import dataclasses
import statistics
import sys
import tempfile
import time
from pathlib import Path

from armstereo.apps.demo import DemoOptions, run_demo
from armstereo.mount import CameraMount
from bench.harness import write_report
from drivers.mock.camera import true_mount
from drivers.mock.profile import REALISTIC, ImageEffects, MockProfile

NONE = MockProfile("none", scene=REALISTIC.scene)


def rows() -> list[tuple[str, MockProfile, bool, bool]]:
    """(label, profile, read the controller's table, hand the software the true camera)."""
    alone = [
        ("kinematics alone (calibrated arm, nominal model used)",
         dataclasses.replace(NONE, name="kinematics", kinematics=True), False),
        ("hand-eye error alone", dataclasses.replace(NONE, name="hand-eye",
                                                     hand_eye=REALISTIC.hand_eye), True),
        ("intrinsics error alone", dataclasses.replace(NONE, name="intrinsics",
                                                       intrinsics=REALISTIC.intrinsics), True),
        ("image effects alone", dataclasses.replace(NONE, name="image", image=REALISTIC.image),
         True),
        ("joint noise alone (encoder noise, ringing)",
         dataclasses.replace(NONE, name="joints", joints=REALISTIC.joints), True),
    ]
    im = REALISTIC.image
    effects = [
        ("image: photon and read noise only", ImageEffects(
            read_noise=im.read_noise, shot_noise_gain=im.shot_noise_gain)),
        ("image: defocus blur only", ImageEffects(blur_sigma_px=im.blur_sigma_px)),
        ("image: vignetting only (no noise)", ImageEffects(vignetting=im.vignetting)),
        ("image: exposure and white balance only", ImageEffects(
            exposure_rel=im.exposure_rel, white_balance_rel=im.white_balance_rel)),
    ]
    return ([("none (desk scene, every source off)", NONE, True, False)]
            + [(label, p, read, False) for label, p, read in alone]
            + [(label, dataclasses.replace(NONE, name="image part", image=fx), True, False)
               for label, fx in effects]
            + [("all sources, nominal model (nothing corrected)", REALISTIC, False, False),
               ("all, after reading the controller's calibration (the demo)", REALISTIC, True,
                False),
               ("all, after also calibrating the camera perfectly", REALISTIC, True, True)])


def run_one(profile: MockProfile, read: bool, calibrated_camera: bool, seed: int,
            method: str) -> dict:
    mount = (true_mount(CameraMount.load(None), profile, seed) if calibrated_camera
             else None)
    options = DemoOptions(profile=profile, read_calibration=read, mount=mount, seed=seed,
                          method=method)
    with tempfile.TemporaryDirectory() as tmp:
        report = run_demo(Path(tmp), options)
    acc = report["accuracy"]
    return {"err": acc["median_abs_rel_depth_error"] * 100, "density": acc["density"] * 100,
            "point_mm": report["point_error_mm"]["median"], "time": report["timings_s"]["total"]}


def cell(values: list[float], fmt: str) -> str:
    mid = statistics.median(values)
    if len(values) == 1:
        return format(mid, fmt)
    return f"{format(mid, fmt)} ({format(min(values), fmt)}-{format(max(values), fmt)})"


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    p.add_argument("--methods", nargs="+", default=["birchfield", "sgbm"])
    p.add_argument("--out", default="bench/results/error_budget.md")
    args = p.parse_args()
    t_start = time.perf_counter()
    run_one(NONE, True, False, 0, "birchfield")  # compile the matcher before timing anything
    lines = [
        "# Error budget of the demo scene (realistic mock profile)",
        "",
        f"`.venv/bin/python -m bench.error_budget --seeds {' '.join(map(str, args.seeds))} "
        f"--methods {' '.join(args.methods)}`: one full demo run per cell and seed (desk scene, "
        "UR5e camera 0.55 m above the table, 80 mm baseline). Cells: median over the seeds "
        "(range in brackets). `depth err` = median |relative depth error| on pixels both views "
        "see; `points` = median distance of the reconstructed points to the true surfaces "
        "(base frame); `density` = share of those pixels with a depth.",
        "",
    ]
    for method in args.methods:
        lines += [f"## {method}", "",
                  "| error sources | depth err % | points mm | density % |",
                  "|---|---|---|---|"]
        for label, profile, read, camera in rows():
            runs = [run_one(profile, read, camera, seed, method) for seed in args.seeds]
            row = (f"| {label} | {cell([r['err'] for r in runs], '.3f')} | "
                   f"{cell([r['point_mm'] for r in runs], '.2f')} | "
                   f"{cell([r['density'] for r in runs], '.1f')} |")
            print(method, row, file=sys.stderr, flush=True)
            lines.append(row)
        lines.append("")
    lines.append(f"{len(rows()) * len(args.seeds) * len(args.methods)} demo runs, "
                 f"{time.perf_counter() - t_start:.0f} s on a shared 2-core machine.")
    write_report("\n".join(lines) + "\n", args.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
