"""Benchmark: the realistic desk when the views differ the way a real camera makes them differ
(issue 26), Birchfield-Tomasi (the defaults and those before issue 26) beside StereoSGBM.

Rows: the desk with only the image effects on (the cell's true camera, no arm or calibration
error, no photometric correction): all of them, then each alone (noise, defocus blur,
vignetting, exposure / white balance); and the demo's workflow on the full realistic cell
(camera calibrated on the cell, photometric correction on, and off). Scores per seed as
bench/error_budget_cell.py (median |relative depth error|, density, point distance) plus the
scene step's objects found and plane tilt; medians over the seeds with their range.

    .venv/bin/python -m bench.radiometric_desk [--seeds 0 1 2 3 4] [--held-out 5 6 7 8 9]
        [--out bench/results/radiometric_desk.md]
"""

from __future__ import annotations

import argparse
import dataclasses
import tempfile
from pathlib import Path

from armstereo.apps.demo import DemoOptions
from armstereo.apps.demo_score import compare_mount
from armstereo.reconstruct.pipeline import reconstruct_pair
from armstereo.recording.remount import remounted
from bench.error_budget_cell import IM, PHOTO, cell, run_cell, variant
from bench.harness import command_line, machine_note, write_report
from drivers.mock.profile import (
    REALISTIC,
    ArmResidual,
    BoardErrors,
    HandEyeErrors,
    ImageEffects,
    IntrinsicsErrors,
    JointErrors,
)

# the demo's options for each (DemoOptions.matcher_options), with these changes; SGBM twice:
# as the demo runs it (pre-smoothed, shift-averaged: DEMO_SGBM) and as OpenCV's defaults
MATCHERS = {"Birchfield-Tomasi": ("birchfield", {}),
            "before issue 26": ("birchfield", {"equalize": False, "plain_fill": None}),
            "the demo's SGBM": ("sgbm", {}),
            "OpenCV's SGBM": ("sgbm", {"presmooth": 0.0, "shifts": 1})}


def effects_only(name: str, effects: ImageEffects):
    """The realistic desk with nothing but ``effects``: no arm, hand-eye, lens or board error."""
    return variant(name, image=effects, joints=JointErrors(), residual=ArmResidual(),
                   board=BoardErrors(), hand_eye=HandEyeErrors(), intrinsics=IntrinsicsErrors())


ROWS = [  # (label, cell, camera, photometric)
    ("image effects alone: all", effects_only("fx", IM), "true", "off"),
    ("noise alone", effects_only("fn", ImageEffects(read_noise=IM.read_noise,
                                                    shot_noise_gain=IM.shot_noise_gain)),
     "true", "off"),
    ("defocus blur alone", effects_only("fb", ImageEffects(blur_sigma_px=IM.blur_sigma_px)),
     "true", "off"),
    ("vignetting alone", effects_only("fv", ImageEffects(vignetting=IM.vignetting)),
     "true", "off"),
    ("exposure / white balance alone",
     effects_only("fe", ImageEffects(exposure_rel=IM.exposure_rel,
                                     white_balance_rel=IM.white_balance_rel)), "true", "off"),
    ("the demo: calibrated, photometric correction on", REALISTIC, "calibrated", "on"),
    ("the demo, photometric correction off", REALISTIC, "calibrated", "off"),
]


def score_seeds(seeds: list[int]) -> dict[tuple[str, str], list[dict]]:
    scores: dict[tuple[str, str], list[dict]] = {}
    for label, profile, camera, photo in ROWS:
        for seed in seeds:
            with tempfile.TemporaryDirectory() as tmp:
                pair, meta, truth, mounts = run_cell(profile, seed, Path(tmp))
                mount = mounts[camera]
                options = dataclasses.replace(PHOTO[photo], model=mount.vignetting)
                for name, (method, changes) in MATCHERS.items():
                    stereo = {**DemoOptions(method=method).matcher_options(), **changes}
                    recon = reconstruct_pair(remounted(pair, mount), method=method,
                                             stereo_options=stereo, photometric=options)
                    scores.setdefault((label, name), []).append(
                        compare_mount(recon, pair, meta, truth))
    return scores


def table(scores) -> list[str]:
    rows = ["| row | matcher | depth err % | density % | points mm | objects found | "
            "plane tilt deg |", "|---|---|---|---|---|---|---|"]
    for label, *_ in ROWS:
        for name in MATCHERS:
            rs = scores[(label, name)]
            scene = [r.get("scene", {}) for r in rs]
            found = [s["objects_found"] for s in scene if "objects_found" in s]
            tilt = [s["plane_tilt_deg"] for s in scene if "plane_tilt_deg" in s]
            rows.append(
                f"| {label} | {name} | "
                f"{cell([r['accuracy']['median_abs_rel_depth_error'] * 100 for r in rs], '.3f')}"
                f" | {cell([r['accuracy']['density'] * 100 for r in rs], '.1f')} | "
                f"{cell([r['point_error_mm']['median'] for r in rs], '.2f')} | "
                f"{cell(found, 'd') if found else '-'} | {cell(tilt, '.2f') if tilt else '-'} |")
    return rows


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2, 3, 4])
    p.add_argument("--held-out", type=int, nargs="*", default=[5, 6, 7, 8, 9])
    p.add_argument("--out", default="bench/results/radiometric_desk.md")
    args = p.parse_args()
    lines = ["# The realistic desk under a real camera's image effects (issue 26)", "",
             f"`{command_line('bench.radiometric_desk')}`  ", machine_note(), "",
             "Median over the seeds (range). `depth err` = median |relative depth error| on "
             "pixels both views see; `points` = median distance to the true surfaces; 7 true "
             "objects. 'alone' rows: the cell's true camera, no photometric correction.", "",
             f"## Seeds {' '.join(map(str, args.seeds))}", "", *table(score_seeds(args.seeds))]
    if args.held_out:
        lines += ["", f"## Held-out seeds {' '.join(map(str, args.held_out))}", "",
                  *table(score_seeds(args.held_out))]
    write_report("\n".join(lines) + "\n", args.out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
