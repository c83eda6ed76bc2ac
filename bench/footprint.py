"""Object footprints on the mock table scene (one pair, ideal profile) per matcher option set,
and the same option sets' bad-2 on the Middlebury/synthetic pairs beside SGBM.

Issue 15 asks for footprints within 5 mm of the truth; the 10 cm crate came out 9-12 mm too
wide (foreground fattening across the half-occluded table beside it). Each seed's pair is
captured once (``run_demo`` with the ideal profile, as tests/armstereo/scene/test_mock_scene.py
does), then reconstructed with every option set given by ``--variant LABEL=JSON`` (options of
``birchfield()``; the defaults always run as ``defaults``), analysed and scored against the
scene's truth. ``--middlebury`` also scores each option set on bench/stereo.py's pairs (bad-2,
one thread; NaN counts as bad) beside StereoSGBM.

    .venv/bin/python -m bench.footprint [--seeds 0 1 2 3] [--variant 'pc={"photo_check": 12}']
        [--middlebury] [--out FILE]
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

import numba
import numpy as np

from armstereo.apps.demo import DemoOptions, run_demo
from armstereo.evaluation.scene_score import score_scene
from armstereo.reconstruct.pipeline import reconstruct_pair
from armstereo.recording import Recording
from armstereo.scene import SceneCloud, analyze_scene
from bench.harness import case_disparity, case_scores, stereo_cases, write_report
from drivers.mock.scene import default_table_scene

OBJECTS = ("crate", "book", "puck", "ball", "block", "marble", "can")


def scene_errors(pair, seed: int, options: dict) -> dict:
    """Per-object errors (mm) of the analysis of ``pair`` matched with ``options``."""
    t0 = time.perf_counter()
    recon = reconstruct_pair(pair, stereo_options=options)
    match_s = recon.timings_s["match"]
    cloud = SceneCloud(np.asarray(recon.points_base, float), recon.colors_bgr, "base", "bench")
    score = score_scene(analyze_scene(cloud), default_table_scene(seed).truth())
    rows = {m.name: dict(length=1000 * m.length_error_m, width=1000 * m.width_error_m,
                         centre=1000 * m.center_error_m, height=1000 * m.height_error_m,
                         partial=m.partial) for m in score.matched}
    points = int(np.isfinite(recon.disparity).sum())
    return dict(objects=rows, missed=list(score.missed), phantoms=len(score.phantoms),
                match_s=match_s, total_s=time.perf_counter() - t0, points=points)


def capture(seed: int, folder: Path, profile: str = "ideal"):
    folder.mkdir(parents=True, exist_ok=True)
    run_demo(folder, DemoOptions(profile=profile, seed=seed))
    return Recording.open(folder / "demo.mcap")[0]


def scene_table(results: dict) -> str:
    lines = ["| option set | seed | crate L/W, centre | worst other L/W, centre (name) | "
             "height worst | found | phantoms | disparities | match s |", "|" + "---|" * 9]
    for label, per_seed in results.items():
        for seed, r in per_seed.items():
            objs = r["objects"]
            c = objs.get("crate")
            crate = (f"{c['length']:+.1f}/{c['width']:+.1f}, {c['centre']:.1f}" if c else "-")
            others = {k: v for k, v in objs.items() if k != "crate" and not v["partial"]}
            if others:
                fp = max(others.items(), key=lambda kv: max(abs(kv[1]["length"]),
                                                            abs(kv[1]["width"])))
                ce = max(others.items(), key=lambda kv: kv[1]["centre"])
                worst = (f"{max(abs(fp[1]['length']), abs(fp[1]['width'])):.1f} ({fp[0]}), "
                         f"{ce[1]['centre']:.1f} ({ce[0]})")
            else:
                worst = "-"
            heights = max((abs(v["height"]) for v in objs.values()), default=float("nan"))
            partial = sorted(k for k, v in objs.items() if v["partial"])
            lines.append(f"| {label} | {seed} | {crate} | {worst} | {heights:.1f} | "
                         f"{len(objs)} (partial: {', '.join(partial) or '-'}) | "
                         f"{r['phantoms']} | {r['points']} | {r['match_s']:.2f} |")
    return "\n".join(lines) + "\n"


def middlebury_table(variants: dict) -> str:
    cases = stereo_cases()
    names = [c.name for c in cases]
    sets = {"StereoSGBM": dict(method="sgbm"), **variants}
    lines = ["| option set | " + " | ".join(names) + " | average | time s |",
             "|" + "---|" * (len(names) + 3)]
    for label, options in sets.items():
        bad, total = [], 0.0
        for case in cases:
            case_disparity(case, options, 1)  # warm-up (compilation)
            t0 = time.perf_counter()
            disp = case_disparity(case, options, 1)
            total += time.perf_counter() - t0
            bad.append(100 * case_scores(case, disp)["bad2"])
        lines.append(f"| {label} | " + " | ".join(f"{b:.2f}" for b in bad)
                     + f" | {np.mean(bad):.2f} | {total:.2f} |")
        print(lines[-1], file=sys.stderr)
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2, 3])
    parser.add_argument("--variant", action="append", default=[], metavar="LABEL=JSON")
    parser.add_argument("--profile", default="ideal", help="mock profile of the demo")
    parser.add_argument("--no-scene", action="store_true", help="skip the scene part")
    parser.add_argument("--middlebury", action="store_true")
    parser.add_argument("--out", type=Path)
    args = parser.parse_args(argv)
    variants = {"defaults": {}}
    for v in args.variant:
        label, _, text = v.partition("=")
        variants[label] = json.loads(text)
    numba.set_num_threads(1)
    parts = []
    if not args.no_scene:
        results = {label: {} for label in variants}
        with tempfile.TemporaryDirectory() as tmp:
            for seed in args.seeds:
                pair = capture(seed, Path(tmp) / f"seed{seed}", args.profile)
                for label, options in variants.items():
                    results[label][seed] = scene_errors(pair, seed, options)
                    c = results[label][seed]["objects"].get("crate", {})
                    print(f"seed {seed} {label}: crate {c}", file=sys.stderr)
        parts.append(scene_table(results))
    if args.middlebury:
        parts.append(middlebury_table(variants))
    text = "\n".join(parts)
    write_report(text, args.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
