"""Benchmark: where the time of ``birchfield()`` goes, stage by stage, beside StereoSGBM.

Each stage is one named function of :mod:`armstereo.reconstruct.stereo` (or of the modules
it calls: ``birchfield.window.aggregate``, ``consensus``, ``speckles``): the worker wraps every one
it finds with a timer and reports its *own* time (without the stages it calls), the median
over the runs; "rest of birchfield()" is what runs in ``birchfield()``'s own body. A stage a
variant does not have (renamed, or inline there) shows as "-" and its time is in the row of
its caller. SGBM runs interleaved with ``birchfield()`` in the same process, one thread each
(``numba.set_num_threads``, ``cv2.setNumThreads``), on the pairs of bench/stereo.py (the four
Middlebury pairs and its two synthetic scenes).

Times are process CPU time by default (``--clock wall`` for wall time): with one thread
they measure the same work, and CPU time moves far less when the machine is shared.
``--masked`` passes validity masks like a rectification's (the pose-based pipeline always
has them; a few stages take another path then). ``--variant NAME=SRC`` measures the
``armstereo`` package of the source tree SRC (e.g. an unpacked ``git archive main``) as NAME;
variants run in turn in fresh processes, ``--rounds`` times, so that each sees the same
machine load. ``--cprofile`` prints cProfile's top functions of the call on cones instead.

Run: ``.venv/bin/python -m bench.stereo_stages [--repeats 9] [--rounds 2] [--masked]
[--variant before=DIR --variant after=.] [--options '{"lr_check": true}'] [--case cones]
[--out bench/results/stereo_stages.md]``.
"""

from __future__ import annotations

import argparse
import importlib
import importlib.util
import json
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

from bench.harness import RESULTS, ROOT, child_command, child_env, stereo_cases, write_report

RESULTS = RESULTS / "stereo_stages.md"

# (module, function, stage label), in the order the default path runs them
STAGES = [
    ("stereo", "_prepare", "input checks"),
    ("stereo", "_grey", "grey conversion"),
    ("stereo", "_texture_strength", "texture maps"),
    ("stereo", "_textureless", "texture maps"),
    ("stereo", "_rewarded", "texture maps"),
    ("stereo", "_highpass", "highpass prefilter"),
    ("stereo", "_with_edges", "edge prefilter"),
    ("stereo", "_match", "match setup (stereo.py)"),
    ("aggregate", "match_image_aggregated", "match setup (aggregate.py)"),
    ("aggregate", "fill_outside", "fill_outside (aggregate.py)"),
    ("aggregate", "match_block", "DP kernels"),  # before the lane kernels
    ("aggregate", "image_bounds", "DP kernels"),
    ("aggregate", "lane_setup", "DP kernels"),  # before block_setup
    ("aggregate", "block_setup", "DP kernels"),
    ("aggregate", "lane_forward", "DP kernels"),
    ("aggregate", "lane_forward_column", "DP kernels"),  # one-column windows, fused.py
    ("aggregate", "lane_backtrack", "DP kernels"),
    ("stereo", "_gradient_step", "sub-pixel: fast"),
    ("stereo", "_median", "median"),
    ("stereo", "_unsupported", "unsupported flat pixels"),
    ("stereo", "_unsupported_rows", "unsupported flat pixels"),
    ("stereo", "_column_rejects", "unsupported flat pixels"),
    ("stereo", "_hidden_by_nearer", "hidden by nearer"),
    # both tests in one row kernel (refine.row_rejects)
    ("stereo", "_flat_and_hidden", "unsupported flat + hidden (one kernel)"),
    ("stereo", "_rows", "unsupported flat + hidden (one kernel)"),
    ("stereo", "left_right_mismatch", "left-right check"),
    ("stereo", "_photo_inconsistent", "photo check"),
    ("stereo", "refine_gradient", "sub-pixel: gradient"),
    ("stereo", "refine_parabola", "sub-pixel: parabola"),
    ("stereo", "_replace_outliers", "consensus median"),  # before consensus.py
    ("stereo", "_consensus_rows", "consensus median"),
    ("consensus", "replace_outliers", "consensus median"),
    ("consensus", "_consensus_rows", "consensus median"),
    ("stereo", "_reject", "reject (NaN bookkeeping)"),
    ("stereo", "_remove_speckles", "speckles"),  # before speckles.py
    ("stereo", "_speckle_codes", "speckles"),
    ("speckles", "remove_speckles", "speckles"),
    ("stereo", "_clip_to_window", "clip to window"),
    ("stereo", "_reject_invalid_partners", "invalid partners"),
    ("stereo", "_masked_map", "rest of birchfield()"),  # the strips' bookkeeping
    ("stereo", "_first_pass", "rest of birchfield()"),
    ("stereo", "_second_pass", "rest of birchfield()"),
    ("stereo", "birchfield", "rest of birchfield()"),
    # the same stages after the split of stereo.py by stage (issue 23)
    ("stereo_inputs", "prepare", "input checks"),
    ("stereo_inputs", "grey", "grey conversion"),
    ("stereo_inputs", "texture_strength", "texture maps"),
    ("stereo_inputs", "rewarded", "texture maps"),
    ("stereo_inputs", "highpass", "highpass prefilter"),
    ("stereo_inputs", "with_edges", "edge prefilter"),
    ("subpixel", "gradient_step", "sub-pixel: fast"),
    ("subpixel", "refine_gradient", "sub-pixel: gradient"),
    ("subpixel", "refine_parabola", "sub-pixel: parabola"),
    ("rejection", "_median", "median"),
    ("rejection", "unsupported", "unsupported flat pixels"),
    ("rejection", "hidden_by_nearer", "hidden by nearer"),
    ("rejection", "_flat_and_hidden", "unsupported flat + hidden (one kernel)"),
    ("rejection", "_rows", "unsupported flat + hidden (one kernel)"),
    ("rejection", "photo_inconsistent", "photo check"),
    ("rejection", "add_rejections", "reject (NaN bookkeeping)"),
    ("rejection", "clip_to_window", "clip to window"),
    ("rejection", "reject_invalid_partners", "invalid partners"),
    ("rejection", "masked_map", "rest of birchfield()"),
    ("rejection", "_first_pass", "rest of birchfield()"),
    # the brightness equalisation and the plain fill (issue 26); the equalisation's first
    # pass is a nested birchfield() call, timed inside "brightness equalisation"
    ("equalize", "equalize", "brightness equalisation"),
    ("normalize", "normalize", "local normalisation"),
    ("plain", "fill_plain", "plain fill"),
]
DP = "DP kernels"
SUBPIXEL = "sub-pixel: fast"
TOTAL = "total birchfield()"
SGBM = "StereoSGBM"
MASK_TURN = 2.0  # degrees
MASK_ZOOM = 1.03


# --- worker (one process, one source tree) ----------------------------------------------------

class StageTimer:
    """Wraps functions so that each call adds its own time (minus nested wrapped calls)."""

    clock = staticmethod(time.process_time)

    def __init__(self):
        self.own: dict[str, float] = {}
        self._stack: list[float] = []  # time spent in nested wrapped calls, per open call

    def wrap(self, func, label: str):
        def timed(*args, **kwargs):
            self._stack.append(0.0)
            t0 = self.clock()
            try:
                return func(*args, **kwargs)
            finally:
                total = self.clock() - t0
                nested = self._stack.pop()
                self.own[label] = self.own.get(label, 0.0) + total - nested
                if self._stack:
                    self._stack[-1] += total
        return timed


def _bench_cases():
    """The pairs of bench/stereo.py."""
    return stereo_cases()


def rectification_masks(shape: tuple[int, ...]) -> tuple:
    """Validity masks like a rectification's (the image turned by +-MASK_TURN degrees and
    enlarged by MASK_ZOOM, black corners outside): for timing the masked code paths."""
    import cv2
    import numpy as np

    H, W = shape[:2]
    ones = np.ones((H, W), np.uint8)
    return tuple(cv2.warpAffine(ones, cv2.getRotationMatrix2D((W / 2, H / 2), turn, MASK_ZOOM),
                                (W, H)) > 0 for turn in (MASK_TURN, -MASK_TURN))


def worker(repeats: int, options: dict, only: list[str] | None, masked: bool) -> dict:
    """Median own time of each stage, of the whole call and of SGBM, per case (seconds)."""
    import cv2
    import numba

    from armstereo.reconstruct import stereo  # from the tree on PYTHONPATH: import it first
    from armstereo.reconstruct.birchfield.window import aggregate

    cases = [c for c in _bench_cases() if not only or c.name in only]
    numba.set_num_threads(1)
    cv2.setNumThreads(1)
    timer = StageTimer()
    modules = {"stereo": stereo, "aggregate": aggregate}
    # split out of stereo.py: older trees lack them
    for part in ("consensus", "speckles", "stereo_inputs", "rejection", "subpixel", "equalize",
                 "normalize", "plain"):
        if importlib.util.find_spec(f"armstereo.reconstruct.{part}") is not None:
            modules[part] = importlib.import_module(f"armstereo.reconstruct.{part}")
    present = []
    for mod, name, label in STAGES:
        func = getattr(modules.get(mod), name, None)
        if func is None:
            continue
        for module in modules.values():  # and where it was imported by name
            if getattr(module, name, None) is func:
                setattr(module, name, timer.wrap(func, label))
        present.append(label)
    out = {"present": present, "cases": {}}
    for case in cases:
        masks = {}
        if masked:
            masks = dict(zip(("left_mask", "right_mask"), rectification_masks(case.left.shape),
                             strict=True))
        runs = _time_case(stereo, case, options, masks, repeats, timer)
        labels = {k for r in runs for k in r}
        out["cases"][case.name] = res = {k: [r.get(k, 0.0) for r in runs] for k in labels}
        print(f"  {case.name}: birchfield {1000 * statistics.median(res[TOTAL]):.1f} ms, "
              f"SGBM {1000 * statistics.median(res[SGBM]):.1f} ms", file=sys.stderr)
    return out


def _time_case(stereo, case, options: dict, masks: dict, repeats: int,
               timer: StageTimer) -> list[dict]:
    """``repeats`` runs of birchfield() then SGBM, after one warm-up of each."""
    args = (case.left, case.right, case.max_disparity)
    options = dict(options, **masks)
    stereo.birchfield(*args, min_disparity=case.min_disparity, **options)
    stereo.sgbm(*args, min_disparity=case.min_disparity, **masks)
    runs = []
    for _ in range(repeats):
        timer.own.clear()
        t0 = timer.clock()
        stereo.birchfield(*args, min_disparity=case.min_disparity, **options)
        t1 = timer.clock()
        stereo.sgbm(*args, min_disparity=case.min_disparity, **masks)
        t2 = timer.clock()
        runs.append(dict(timer.own, **{TOTAL: t1 - t0, SGBM: t2 - t1}))
    return runs


def profile_cones(options: dict, repeats: int) -> None:
    """cProfile of ``repeats`` default calls on cones (own time, top 30 functions)."""
    import cProfile
    import pstats

    import cv2
    import numba

    from armstereo.reconstruct.stereo import birchfield

    numba.set_num_threads(1)
    cv2.setNumThreads(1)
    case = next(c for c in _bench_cases() if c.name == "cones")
    birchfield(case.left, case.right, case.max_disparity, **options)
    prof = cProfile.Profile()
    prof.enable()
    for _ in range(repeats):
        birchfield(case.left, case.right, case.max_disparity, **options)
    prof.disable()
    pstats.Stats(prof).sort_stats("tottime").print_stats(30)


# --- parent: variants side by side ------------------------------------------------------------

def run_worker(src: str | None, args) -> dict:
    env = child_env(src=src)  # src: that tree's armstereo package first on the path
    cmd = child_command("bench.stereo_stages", "--worker", "--repeats", str(args.repeats),
                        "--options", args.options, "--clock", args.clock)
    cmd += ["--masked"] if args.masked else []
    for name in args.case or ():
        cmd += ["--case", name]
    done = subprocess.run(cmd, env=env, capture_output=True, text=True)
    sys.stderr.write(done.stderr)
    done.check_returncode()
    return json.loads(done.stdout.strip().splitlines()[-1])


def merge(results: list[dict]) -> dict:
    """Median per stage over all runs of all rounds of one variant (milliseconds)."""
    present = results[0]["present"]
    cases = {}
    for name in results[0]["cases"]:
        pooled: dict[str, list[float]] = {}
        for res in results:
            for label, values in res["cases"][name].items():
                pooled.setdefault(label, []).extend(values)
        cases[name] = {k: 1000 * statistics.median(v) for k, v in pooled.items()}
    return {"present": present, "cases": cases}


def stage_rows() -> list[str]:
    rows = []
    for _, _, label in STAGES:
        if label not in rows:
            rows.append(label)
    return rows + [TOTAL, SGBM]


def stage_table(case: str, variants: dict[str, dict]) -> str:
    names = list(variants)
    head = ["stage"] + [f"{n} ms" for n in names]
    if len(names) == 2:
        head.append(f"{names[1]} / {names[0]}")
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for label in stage_rows():
        cells, values = [], []
        for n in names:
            res = variants[n]
            v = res["cases"][case].get(label)
            shown = label in (TOTAL, SGBM) or label in res["present"]
            cells.append("-" if not shown else f"{v or 0.0:.2f}")
            values.append(v if shown else None)
        if all(v is None or v == 0 for v in values):
            continue
        if len(names) == 2:
            a, b = values
            cells.append(f"{b / a:.2f}" if a and b is not None and a > 0.05 else "")
        bold = label in (TOTAL, SGBM)
        lines.append("| " + " | ".join(
            [f"**{label}**" if bold else label] + cells) + " |")
    return "\n".join(lines) + "\n"


def summary_table(variants: dict[str, dict]) -> str:
    head = ["pair", "variant", "birchfield ms", "DP ms", "outside the DP ms", "SGBM ms",
            "birchfield / SGBM", "sub-pixel / DP"]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    first = next(iter(variants.values()))
    for case in first["cases"]:
        for name, res in variants.items():
            r = res["cases"][case]
            total, dp, sgbm = r[TOTAL], r.get(DP, 0.0), r[SGBM]
            sub = r.get(SUBPIXEL, 0.0)
            lines.append("| " + " | ".join([
                case, name, f"{total:.1f}", f"{dp:.1f}", f"{total - dp:.1f}", f"{sgbm:.1f}",
                f"{total / sgbm:.2f}", f"{100 * sub / dp:.1f} %" if dp else ""]) + " |")
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=9, help="timed runs per case and round")
    parser.add_argument("--rounds", type=int, default=1,
                        help="variants run in turn this many times (medians over all runs)")
    parser.add_argument("--variant", action="append", default=[], metavar="NAME=SRC",
                        help="measure the armstereo package under SRC as NAME; repeat to "
                             "compare (default: this checkout)")
    parser.add_argument("--options", default="{}", help="JSON of birchfield() options")
    parser.add_argument("--case", action="append", help="only this pair (repeatable)")
    parser.add_argument("--masked", action="store_true",
                        help="pass rectification-like validity masks (black corners)")
    parser.add_argument("--clock", choices=("cpu", "wall"), default="cpu",
                        help="process CPU time (default: steadier on a shared machine, and "
                             "the same as wall time for one thread) or wall time")
    parser.add_argument("--cprofile", action="store_true",
                        help="print cProfile's view of the call on cones and stop")
    parser.add_argument("--out", type=Path, default=None,
                        help=f"markdown file to write (e.g. {RESULTS.relative_to(ROOT)})")
    parser.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    options = json.loads(args.options)
    if args.clock == "wall":
        StageTimer.clock = staticmethod(time.perf_counter)
    if args.worker:
        print(json.dumps(worker(args.repeats, options, args.case, args.masked)))
        return 0
    if args.cprofile:
        profile_cones(options, args.repeats)
        return 0
    variants = dict(v.split("=", 1) for v in args.variant) or {"this checkout": None}
    raw: dict[str, list[dict]] = {name: [] for name in variants}
    load = []
    for i in range(args.rounds):
        for name, src in variants.items():
            print(f"round {i + 1}, {name}:", file=sys.stderr)
            load.append(os.getloadavg()[0])
            raw[name].append(run_worker(src, args))
    merged = {name: merge(runs) for name, runs in raw.items()}
    first = next(iter(merged.values()))
    parts = [f"# Stage times of birchfield() beside StereoSGBM (one thread)\n\n"
             f"Command: `.venv/bin/python -m bench.stereo_stages "
             f"{' '.join(argv if argv is not None else sys.argv[1:])}`  \n"
             f"Date: {time.strftime('%Y-%m-%d')}; {os.cpu_count()} cores, load average "
             f"{min(load):.1f}-{max(load):.1f} during the run; options {args.options}"
             f"{', rectification-like masks' if args.masked else ''}. "
             f"Medians of {args.repeats} x {args.rounds} runs per variant, in milliseconds "
             f"of {'process CPU' if args.clock == 'cpu' else 'wall'} time.\n",
             "## Per pair\n\n" + summary_table(merged)]
    for case in first["cases"]:
        parts.append(f"## Stages: {case}\n\n" + stage_table(case, merged))
    text = "\n".join(parts)
    write_report(text, args.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
