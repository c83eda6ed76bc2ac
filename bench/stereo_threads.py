"""Does the matcher's threading slow the OpenCV/numpy stages that run right after it?

numba's parallel layer (``prange``) runs on OpenMP by default here; GNU OpenMP workers spin
for a while after each parallel region, which can steal the cores from whatever runs next.
``birchfield()`` matches rows on short-lived Python threads instead. This script times a
pipeline-like stage (``cv2.remap`` of a 1280x960 colour image, then a colour conversion and a
blur) right after each of:

- ``numba serial``: a single-threaded numba kernel (the reference),
- ``birchfield threads=1`` and ``threads=2``: the matcher on a 640x480 pair, 64 disparities,
- ``numba prange``: the same kernel with ``parallel=True``.

The four alternate round by round inside one process, so that they meet the same load from
the rest of the machine; medians over the rounds. One process per OpenMP setting (read once,
at load): the defaults, ``OMP_WAIT_POLICY=PASSIVE`` and the ``workqueue`` threading layer.
Run: ``.venv/bin/python -m bench.stereo_threads [--out bench/results/stereo_threads.md]``.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

from bench.harness import RESULTS, child_command, child_env, command_line, write_report

RESULTS = RESULTS / "stereo_threads.md"
SETTINGS = [
    ("OpenMP defaults", {}),
    ("OMP_WAIT_POLICY=PASSIVE", {"OMP_WAIT_POLICY": "PASSIVE"}),
    ("NUMBA_THREADING_LAYER=workqueue", {"NUMBA_THREADING_LAYER": "workqueue"}),
]
BEFORE = ("numba serial", "birchfield threads=1", "birchfield threads=2", "numba prange")
ROUNDS = 30


def probe() -> dict:
    """In this process: median stage times (ms) after each of :data:`BEFORE`, interleaved."""
    import cv2
    import numba
    import numpy as np

    from armstereo.reconstruct.stereo import birchfield

    rng = np.random.default_rng(0)
    scene = cv2.GaussianBlur((rng.random((480, 660, 3)) * 255).astype(np.uint8), (0, 0), 1.2)
    left, right = scene[:, 20:], scene[:, :640]
    big = (rng.random((960, 1280, 3)) * 255).astype(np.uint8)
    mx, my = np.meshgrid(np.arange(1280, dtype=np.float32) * 0.99 + 3,
                         np.arange(960, dtype=np.float32) * 0.99 + 2)
    field = rng.random((480, 640)).astype(np.float32)

    def kernel(a):
        out = np.empty_like(a)
        for i in numba.prange(a.shape[0]):
            for j in range(a.shape[1]):
                out[i, j] = np.sqrt(a[i, j]) * 2.0
        return out

    serial, parallel = numba.njit(kernel), numba.njit(parallel=True)(kernel)
    before = dict(zip(BEFORE, (lambda: serial(field),
                               lambda: birchfield(left, right, 63, threads=1),
                               lambda: birchfield(left, right, 63, threads=2),
                               lambda: parallel(field)), strict=True))
    times = {name: {"remap": [], "convert+blur": []} for name in BEFORE}
    for round_ in range(ROUNDS + 1):
        for name, run in before.items():
            run()
            t0 = time.perf_counter()
            cv2.remap(big, mx, my, cv2.INTER_LINEAR)
            t1 = time.perf_counter()
            cv2.GaussianBlur(cv2.cvtColor(big, cv2.COLOR_BGR2GRAY), (0, 0), 2)
            t2 = time.perf_counter()
            if round_:  # the first round compiles and warms up
                times[name]["remap"].append(1000 * (t1 - t0))
                times[name]["convert+blur"].append(1000 * (t2 - t1))
    med = {n: {k: statistics.median(v) for k, v in t.items()} for n, t in times.items()}
    return {"layer": numba.threading_layer(), "times": med}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=RESULTS, help="markdown file to write")
    parser.add_argument("--probe", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.probe:
        print(json.dumps(probe()))
        return 0
    head = "| setting (layer) | " + " | ".join(f"after {b}" for b in BEFORE) + " |"
    lines = ["Median ms of remap / convert+blur right after each step; compare each column "
             "with 'after numba serial' in the same row (same process, same load).\n", head,
             "|---" * (len(BEFORE) + 1) + "|"]
    for label, env in SETTINGS:
        proc = subprocess.run(child_command("bench.stereo_threads", "--probe"), check=True,
                              capture_output=True, text=True, env=child_env({**os.environ, **env}))
        r = json.loads(proc.stdout.splitlines()[-1])
        cells = [f"{t['remap']:.2f} / {t['convert+blur']:.2f}" for t in r["times"].values()]
        lines.append(f"| {label} ({r['layer']}) | " + " | ".join(cells) + " |")
        print(lines[-1], file=sys.stderr)
    text = (f"# Stage times right after the matcher (threading)\n\nCommand: "
            f"`{command_line('bench.stereo_threads', [])}`  \nDate: {time.strftime('%Y-%m-%d')}; "
            f"{os.cpu_count()} cores; {ROUNDS} interleaved rounds per process.\n\n"
            + "\n".join(lines) + "\n")
    write_report(text, args.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
