"""Where birchfield()'s time goes: its scanline matcher against the rest, and SGBM, per pair.

One thread each (numba and OpenCV), process CPU time of the calling thread (steadier than wall
time on a shared machine), median of ``--repeats`` runs after a warm-up, the peers interleaved
run by run. The matcher's share is the time spent in
``armstereo.reconstruct.birchfield.window.aggregate.match_image_aggregated`` during the call; the
rest is sub-pixel refinement and postprocessing. Pairs: the Middlebury pairs of tests/data,
with the disparity window of bench/stereo.py.

To compare two source trees, run the script once per tree with it first on the path:
``PYTHONPATH=TREE .venv/bin/python -m bench.dp_lanes`` (the script reads the pairs from this
checkout). ``--parts`` also splits the matcher into its kernels (BT intervals of the image,
per-block setup, forward pass, backtrack; medians, so they need not add up).

    .venv/bin/python -m bench.dp_lanes [--repeats 7] [--parts]
"""

from __future__ import annotations

import argparse
import json
import statistics
import time
from pathlib import Path

import cv2
import numba

import armstereo
import armstereo.reconstruct.birchfield.window.aggregate as aggregate
import armstereo.reconstruct.stereo as stereo
from bench.harness import MIDDLEBURY, MIDDLEBURY_NAMES

PAIRS = MIDDLEBURY_NAMES
# the blocks' set-up: numpy for the whole image since the cold-start work, a kernel per block
# before (the lane_setup column of older results)
SETUP = "block_setup" if hasattr(aggregate, "block_setup") else "lane_setup"
KERNELS = ("image_bounds", SETUP, "lane_forward", "lane_backtrack")


class MatchClock:
    """Wraps stereo's matcher entry point and adds up the thread CPU time spent in it."""

    def __init__(self) -> None:
        self.inner = stereo.match_image_aggregated
        self.total = 0.0

    def __call__(self, *args, **kwargs):
        start = time.thread_time()
        try:
            return self.inner(*args, **kwargs)
        finally:
            self.total += time.thread_time() - start


class KernelClocks:
    """Wraps the matcher's kernels as ``aggregate`` calls them and adds up their thread CPU."""

    def __init__(self) -> None:
        self.total = dict.fromkeys(KERNELS, 0.0)
        for name in KERNELS:
            setattr(aggregate, name, self._timed(name, getattr(aggregate, name)))
        if hasattr(aggregate, "lane_forward_column"):  # the fused pass of one-column windows
            aggregate.lane_forward_column = self._timed("lane_forward",
                                                        aggregate.lane_forward_column)

    def _timed(self, name, kernel):
        def timed(*args):
            start = time.thread_time()
            try:
                return kernel(*args)
            finally:
                self.total[name] += time.thread_time() - start
        return timed

    def reset(self) -> None:
        self.total = dict.fromkeys(KERNELS, 0.0)


def measure(name: str, clock: MatchClock, repeats: int,
            kernels: KernelClocks | None = None) -> dict[str, float]:
    meta = json.loads((MIDDLEBURY / name / "meta.json").read_text())
    left = cv2.imread(str(MIDDLEBURY / name / meta["left"]))
    right = cv2.imread(str(MIDDLEBURY / name / meta["right"]))
    max_d = -(-(meta["max_disp"] + 1) // 16) * 16 - 1  # SGBM's multiple of 16, as stereo.py
    runs: dict[str, list[float]] = {"birchfield": [], "match": [], "sgbm": []}
    runs.update({k: [] for k in (KERNELS if kernels else ())})
    for i in range(repeats + 1):  # the first run warms up (and compiles)
        clock.total = 0.0
        if kernels:
            kernels.reset()
        start = time.thread_time()
        stereo.birchfield(left, right, max_d, threads=1)
        whole, match = time.thread_time() - start, clock.total
        start = time.thread_time()
        stereo.sgbm(left, right, max_d)
        if i:
            runs["birchfield"].append(whole)
            runs["match"].append(match)
            runs["sgbm"].append(time.thread_time() - start)
            for k in KERNELS if kernels else ():
                runs[k].append(kernels.total[k])
    return {key: 1000 * statistics.median(v) for key, v in runs.items()}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=7)
    parser.add_argument("--parts", action="store_true", help="split the matcher's time")
    args = parser.parse_args(argv)
    numba.set_num_threads(1)
    cv2.setNumThreads(1)
    clock = MatchClock()
    stereo.match_image_aggregated = clock
    print(f"armstereo from {Path(armstereo.__file__).parent}; ms of thread CPU, median of "
          f"{args.repeats}")
    kernels = KernelClocks() if args.parts else None
    extra = " | bounds | setup | forward | backtrack" if args.parts else ""
    print(f"| pair | birchfield() | its matcher | the rest | SGBM | matcher / SGBM{extra} |")
    print("|---|---|---|---|---|---|" + "---|" * (4 if args.parts else 0))
    for name in PAIRS:
        t = measure(name, clock, args.repeats, kernels)
        parts = "".join(f" | {t[k]:.1f}" for k in KERNELS) if args.parts else ""
        print(f"| {name} | {t['birchfield']:.1f} | {t['match']:.1f} | "
              f"{t['birchfield'] - t['match']:.1f} | {t['sgbm']:.1f} | "
              f"{t['match'] / t['sgbm']:.2f}{parts} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
