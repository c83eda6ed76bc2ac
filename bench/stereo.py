"""Benchmark: Birchfield-Tomasi (armstereo) against OpenCV StereoSGBM with the same threads.

Both matchers get the same disparity window on the four Middlebury v2 pairs (tests/data) and on
synthetic rectified scenes rendered here with exact ground truth (textured planes, slanted and
fronto-parallel, seen by two pinhole cameras; supersampled, with sensor noise). Scores: bad-2
(share of non-occluded pixels with |error| > 2 px or no answer) leaving out the left band of
width ``min_disparity + max_disparity`` where SGBM answers nothing, and the median time of
several runs, the two peers interleaved. Targets (issue 14): bad-2 of Birchfield-Tomasi at most
SGBM's on each pair, time at most SGBM's. ``--variants`` also scores option sets of
``birchfield()``: the measurements behind its defaults (the real-photograph side of them is
bench/real_multiview.py).

Run: ``.venv/bin/python -m bench.stereo [--repeats 7] [--threads 1 2] [--variants]
[--out bench/results/stereo.md]``.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

from armstereo.reconstruct.stereo import PAPER_OPTIONS
from bench.harness import (
    RESULTS,
    Case,
    case_disparity,
    case_scores,
    command_line,
    interleaved,
    machine_note,
    median_time,
    set_threads,
    stereo_cases,
    write_report,
)

PEERS = {"Birchfield-Tomasi": dict(method="birchfield"), "StereoSGBM": dict(method="sgbm")}
# Options of birchfield() scored beside the defaults: the measurements behind the defaults.
PREVIOUS_DEFAULTS = dict(cost_window=(1, 1), slant_penalty=None, postprocess="paper",
                         texture_threshold=0.0, reward_texture=0.0, speckle_size=0,
                         subpixel="gradient", occlusions="nan", consensus_size=0)
VARIANTS = {
    "defaults": {},
    "before issue 14 item 2 (column_support=False, consensus_size=0)": dict(
        column_support=False, consensus_size=0),
    "column_support=False": dict(column_support=False),
    "consensus_size=0": dict(consensus_size=0),
    "consensus_size=7": dict(consensus_size=7),
    "consensus_size=11": dict(consensus_size=11),
    "texture_threshold=0, consensus_size=0 (dense, no consensus)": dict(
        texture_threshold=0.0, consensus_size=0),
    "column_smoothing=(1, 4)": dict(column_smoothing=(1, 4)),
    "column_smoothing=(0.5, 4)": dict(column_smoothing=(0.5, 4)),
    "column_smoothing=(1.5, 6)": dict(column_smoothing=(1.5, 6)),
    "column_smoothing=(2, 8)": dict(column_smoothing=(2, 8)),
    "column_smoothing=(1, 4), consensus_size=0": dict(column_smoothing=(1, 4),
                                                       consensus_size=0),
    "occlusion_penalty=15": dict(occlusion_penalty=15),
    "slant_penalty=10": dict(slant_penalty=10),
    "previous defaults (paper DP + its postprocessing + gradient sub-pixel)": PREVIOUS_DEFAULTS,
    "PAPER_OPTIONS (the paper's matcher as published)": PAPER_OPTIONS,
    "texture_threshold=0 (dense)": dict(texture_threshold=0.0),
    "texture_threshold=0, reward_texture=0": dict(texture_threshold=0.0, reward_texture=0.0),
    "texture_threshold=0.5": dict(texture_threshold=0.5),
    "cost_window=(1, 1)": dict(cost_window=(1, 1)),
    "cost_window=(3, 3)": dict(cost_window=(3, 3)),
    "cost_window=(1, 5)": dict(cost_window=(1, 5)),
    "slant_penalty=None": dict(slant_penalty=None),
    "slant_penalty=5": dict(slant_penalty=5),
    "speckle_size=0": dict(speckle_size=0),
    "postprocess=paper": dict(postprocess="paper"),
    "postprocess=none": dict(postprocess="none"),
    "subpixel=none": dict(subpixel="none"),
    "subpixel=gradient": dict(subpixel="gradient"),
    "occlusions=fill (paper's background fill)": dict(occlusions="fill"),
    "lr_check=True": dict(lr_check=True),
    "occlusion_penalty=35": dict(occlusion_penalty=35),
    "match_reward=3": dict(match_reward=3),
    "color=sum (single-pixel kernels)": dict(color="sum"),
    "prefilter=none, occlusion_margin=1 (before the Cones work)": dict(prefilter="none",
                                                                       occlusion_margin=1),
    "prefilter=none (intensities)": dict(prefilter="none"),
    "occlusion_margin=1": dict(occlusion_margin=1),
    "occlusion_margin=3": dict(occlusion_margin=3),
    "occlusion_margin=8": dict(occlusion_margin=8),
    "edge_cap=10": dict(edge_cap=10),
    "edge_cap=15": dict(edge_cap=15),
    "edge_cap=20": dict(edge_cap=20),
    "match_reward=6": dict(match_reward=6),
    "prefilter=highpass (gain 2)": dict(prefilter="highpass"),
    "prefilter=highpass, gain 1": dict(prefilter="highpass", prefilter_gain=1.0),
}


def run_peers(case: Case, repeats: int, threads: int) -> dict[str, dict]:
    """Both peers, interleaved run by run so that both see the same machine load; median
    time over ``repeats`` runs after one warm-up, scores of the last run."""
    got = interleaved({name: (lambda o=options: case_disparity(case, o, threads))
                       for name, options in PEERS.items()}, repeats)
    return {name: dict(case_scores(case, disp), time=t) for name, (t, disp) in got.items()}


def run_variants(cases: list[Case], threads: int) -> dict[str, dict]:
    """Averages over the cases for each option set (one timed run after a warm-up)."""
    out = {}
    for label, options in VARIANTS.items():
        rows = []
        for case in cases:
            t, disp = median_time(lambda c=case, o=options: case_disparity(c, o, threads), 1)
            rows.append(dict(case_scores(case, disp), time=t))
        out[label] = {k: float(np.mean([r[k] for r in rows])) for k in
                      ("bad2", "wrong_answers", "invalid")}
        out[label]["time"] = float(sum(r["time"] for r in rows))
        print(f"  {label}: bad-2 {100 * out[label]['bad2']:.2f} %", file=sys.stderr)
    return out


def peers_table(rows: list[tuple[Case, dict[str, dict]]]) -> tuple[str, dict]:
    a, b = PEERS
    head = ["pair", "size", "disparities", f"{a} bad-2 %", f"{b} bad-2 %", f"{a} ms",
            f"{b} ms", "time ratio"]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for case, res in rows:
        H, W = case.left.shape[:2]
        lines.append("| " + " | ".join([
            case.name, f"{W}x{H}",
            f"{case.min_disparity}..{case.min_disparity + case.max_disparity}",
            f"{100 * res[a]['bad2']:.2f}", f"{100 * res[b]['bad2']:.2f}",
            f"{1000 * res[a]['time']:.1f}", f"{1000 * res[b]['time']:.1f}",
            f"{res[a]['time'] / res[b]['time']:.2f}"]) + " |")
    summary = {}
    for name in PEERS:
        summary[name] = dict(bad2=float(np.mean([r[name]["bad2"] for _, r in rows])),
                             time=float(sum(r[name]["time"] for _, r in rows)))
    summary["bad2_ratio"] = summary[a]["bad2"] / summary[b]["bad2"]
    summary["time_ratio"] = summary[a]["time"] / summary[b]["time"]
    lines.append("| " + " | ".join([
        "**average / total**", "", "", f"**{100 * summary[a]['bad2']:.2f}**",
        f"**{100 * summary[b]['bad2']:.2f}**", f"**{1000 * summary[a]['time']:.0f}**",
        f"**{1000 * summary[b]['time']:.0f}**", f"**{summary['time_ratio']:.2f}**"]) + " |")
    worse = [case.name for case, res in rows if res[a]["bad2"] > res[b]["bad2"]]
    slower = [case.name for case, res in rows if res[a]["time"] > res[b]["time"]]
    verdict = (f"Averaged bad-2 ratio {summary['bad2_ratio']:.2f}, total median time ratio "
               f"{summary['time_ratio']:.2f}. Per-pair targets (bad-2 and time at most SGBM's): "
               f"bad-2 {'met' if not worse else 'MISSED on ' + ', '.join(worse)}; time "
               f"{'met' if not slower else 'MISSED on ' + ', '.join(slower)}.")
    return "\n".join(lines) + "\n\n" + verdict + "\n", summary


def variants_table(res: dict[str, dict]) -> str:
    lines = ["| birchfield() options | bad-2 % | wrong answers % | no answer % | total ms |",
             "|---|---|---|---|---|"]
    for label, r in res.items():
        lines.append(f"| {label} | {100 * r['bad2']:.2f} | {100 * r['wrong_answers']:.2f} | "
                     f"{100 * r['invalid']:.2f} | {1000 * r['time']:.0f} |")
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=7, help="timed runs per case (median)")
    parser.add_argument("--threads", type=int, nargs="+", default=[1],
                        help="thread counts to run the peers with (default 1; e.g. 1 2)")
    parser.add_argument("--variants", action="store_true",
                        help="also score birchfield() option sets (one thread)")
    parser.add_argument("--out", type=Path, default=RESULTS / "stereo.md",
                        help="markdown file to write")
    args = parser.parse_args(argv)
    cases = stereo_cases()
    parts = [f"# Stereo benchmark: Birchfield-Tomasi vs StereoSGBM\n\n"
             f"Command: `{command_line('bench.stereo', argv)}`"
             f"  \nDate: {time.strftime('%Y-%m-%d')}; {machine_note()}\n"]
    for n in args.threads:
        set_threads(n)
        rows = []
        for case in cases:
            res = run_peers(case, args.repeats, n)
            rows.append((case, res))
            print(f"{n} thread(s) {case.name}: " + ", ".join(
                f"{k} bad-2 {100 * r['bad2']:.2f} % in {1000 * r['time']:.1f} ms"
                for k, r in res.items()), file=sys.stderr)
        table, _ = peers_table(rows)
        parts.append(f"## {n} thread{'s' if n > 1 else ''} each\n\n{table}")
    if args.variants:
        set_threads(1)
        print("birchfield() options:", file=sys.stderr)
        parts.append("## birchfield() options (one thread, averages over the six pairs)\n\n"
                     + variants_table(run_variants(cases, 1)))
    parts.append(NOTES)
    write_report("\n".join(parts), args.out)
    return 0


NOTES = """
Scoring: bad-2 = share of non-occluded pixels with ground truth whose error exceeds 2 px or
that have no answer, leaving out the left band `x < min + max disparity` (where SGBM answers
nothing); averaged over the pairs. "Wrong answers" = share of the answered pixels with ground
truth (occluded ones included) whose error exceeds 2 px. Times: median over the runs after one
warm-up, both peers interleaved run by run; threads set with `cv2.setNumThreads` and
`numba.set_num_threads` (birchfield matches chunks of rows on that many threads and runs the
other steps on strips of rows; scaling in bench/results/stereo_scaling.md). Same disparity
window for both: the Middlebury v2 range rounded up to SGBM's multiple of 16. Option sets:
one timed run each, so their times are rough. The machine is shared: times move by 10-20 %
from run to run, the ratios much less. Whether the matcher's threads slow the stages after
it: bench/stereo_threads.py (stereo_threads.md).
"""


if __name__ == "__main__":
    sys.exit(main())
