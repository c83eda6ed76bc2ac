"""Benchmark: how ``birchfield()`` scales from one thread to two, beside StereoSGBM.

The pairs of bench/stereo.py (four Middlebury pairs, two synthetic scenes; 0.1-0.3 megapixels)
and two larger inputs made from Cones by tiling both views 2x2 and 3x3 (0.68 and 1.5
megapixels, the disparity window unchanged; a camera of 1-2 megapixels gives images of this
size). For each pair the calls at one and at two threads alternate round by round, which one
goes first alternating too, so that both meet the same machine load; the speed-up is the
median over the rounds of each round's ratio (a slow spell of the shared machine hits both
calls of a round alike). Threads are set with ``numba.set_num_threads`` and
``cv2.setNumThreads``, as for a user who calls ``birchfield()`` without ``threads``. Every
pair's maps at one and at two threads are checked to be identical.

Run: ``.venv/bin/python -m bench.stereo_scaling [--rounds 15] [--out
bench/results/stereo_scaling.md]``.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

import numpy as np

from armstereo.reconstruct.stereo import birchfield, sgbm
from bench.harness import (
    RESULTS,
    command_line,
    machine_note,
    set_threads,
    stereo_cases,
    timed,
    write_report,
)

RESULTS = RESULTS / "stereo_scaling.md"
TILES = (2, 3)  # Cones tiled n x n


def cases() -> list[tuple[str, np.ndarray, np.ndarray, int, int]]:
    """``(name, left, right, min_disparity, max_disparity)`` of every pair."""
    out = [(c.name, c.left, c.right, c.min_disparity, c.max_disparity)
           for c in stereo_cases()]
    cones = next(c for c in out if c[0].startswith("cones"))
    for n in TILES:
        left, right = (np.ascontiguousarray(np.tile(img, (n, n, 1))) for img in cones[1:3])
        out.append((f"cones tiled {n}x{n}", left, right, *cones[3:]))
    return out


def cpu_jiffies() -> tuple[int, int] | None:
    """(steal, total) jiffies of all CPUs so far (Linux ``/proc/stat``; None elsewhere):
    time the hypervisor gave the machine's virtual CPUs to others."""
    try:
        fields = [int(v) for v in Path("/proc/stat").read_text().split("\n")[0].split()[1:]]
    except (OSError, ValueError):
        return None
    return (fields[7] if len(fields) > 7 else 0), sum(fields)


def measure(case, rounds: int) -> dict:
    """Median times at 1 and 2 threads and the median per-round speed-up, for both peers, and
    the share of CPU time stolen by the hypervisor meanwhile."""
    name, left, right, dmin, dmax = case
    before = cpu_jiffies()
    peers = {"birchfield": birchfield, "sgbm": sgbm}
    res = {}
    for peer, func in peers.items():
        maps = {}
        for n in (1, 2):  # warm-up (and the compile on a first run)
            set_threads(n)
            maps[n] = func(left, right, dmax, min_disparity=dmin)
        # ours must not depend on the threads (SGBM's is not ours to check)
        if peer == "birchfield" and not np.array_equal(maps[1], maps[2], equal_nan=True):
            raise SystemExit(f"{name}: birchfield gives another map at two threads")
        times = {1: [], 2: []}
        for i in range(rounds):
            for n in ((1, 2) if i % 2 == 0 else (2, 1)):
                set_threads(n)
                times[n].append(timed(func, left, right, dmax, min_disparity=dmin)[1])
        res[peer] = dict(one=statistics.median(times[1]), two=statistics.median(times[2]),
                         speedup=statistics.median(a / b for a, b in zip(times[1], times[2],
                                                                         strict=True)))
    res["pixels"] = left.shape[0] * left.shape[1]
    after = cpu_jiffies()
    res["steal"] = (None if before is None or after is None or after[1] == before[1]
                    else (after[0] - before[0]) / (after[1] - before[1]))
    return res


def table(rows: list[tuple[str, dict]]) -> str:
    lines = ["| pair | megapixels | birchfield 1 thread (ms) | 2 threads (ms) | speed-up | "
             "SGBM 1 thread (ms) | 2 threads (ms) | speed-up | CPU stolen |",
             "|---|---|---|---|---|---|---|---|---|"]
    for name, r in rows:
        b, s = r["birchfield"], r["sgbm"]
        steal = "-" if r["steal"] is None else f"{100 * r['steal']:.1f} %"
        lines.append(f"| {name} | {r['pixels'] / 1e6:.2f} | {1000 * b['one']:.1f} | "
                     f"{1000 * b['two']:.1f} | {b['speedup']:.2f} | {1000 * s['one']:.1f} | "
                     f"{1000 * s['two']:.1f} | {s['speedup']:.2f} | {steal} |")
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=15, help="rounds per pair (median)")
    parser.add_argument("--out", type=Path, default=RESULTS, help="markdown file to write")
    args = parser.parse_args(argv)
    rows = []
    for case in cases():
        rounds = args.rounds if case[1].size < 3e6 else max(5, args.rounds // 3)
        rows.append((case[0], measure(case, rounds)))
        r = rows[-1][1]
        print(f"{case[0]}: birchfield {r['birchfield']['speedup']:.2f}x, "
              f"SGBM {r['sgbm']['speedup']:.2f}x", file=sys.stderr)
    text = (f"# birchfield() from one thread to two\n\nCommand: "
            f"`{command_line('bench.stereo_scaling', argv)}`  \n"
            f"Date: {time.strftime('%Y-%m-%d')}; {machine_note()}\n\n"
            f"{table(rows)}\n{NOTES}")
    write_report(text, args.out)
    return 0


NOTES = """\
Speed-up: median over the rounds of (time at one thread) / (time at two threads), the two
calls of a round run back to back; times: medians. CPU stolen: the share of the virtual
CPUs' time the hypervisor gave to other machines while the pair ran (`/proc/stat`); two
threads need both CPUs, so they suffer more from it than one. Fewer rounds (a third) for
the 3x3 tiles. birchfield()'s maps at one and two threads are identical for every pair
(checked by the script).
What runs on the threads (armstereo/reconstruct/stereo.py, birchfield/aggregate.py): the
grey images, edge prefilter and texture maps, the sub-pixel step and median, the flat-pixel
and hidden tests (the column test on strips of columns), the consensus median, on strips of
rows; the programme's set-up and matching on chunks of rows taken in turn by the threads; the
speckle filter on strips with a band around each cut (armstereo/reconstruct/speckles.py) once
the image is at least 4 x speckle_size rows high. What does not: thread start-up, the
bookkeeping between the steps, and on the small pairs the speckle filter; every step is a
millisecond or two there, so the hand-offs weigh more.
"""


if __name__ == "__main__":
    sys.exit(main())
