"""Cold start of the Birchfield-Tomasi matcher: numba compile time of the default path.

Each repeat runs two fresh Python processes that share one new, empty ``NUMBA_CACHE_DIR``:

- *cold*: the first ``birchfield(...)`` call compiles every kernel the options use; its time
  minus the median of the warm calls that follow (same process) is the compile cost;
- *cached*: the same call in a second process loads the kernels from that cache.

Wall and process CPU time are both reported: the machine may be shared, and CPU time is the
steadier number (the compile is single-threaded; the warm match runs on ``--threads``). The
cold run also records numba's ``numba:compile`` events, so the compile cost is broken down
per kernel (inclusive: with the kernels it calls; own: without the nested compiles).

The pair is the mock demo's: the default table scene rendered from two poses 0.55 m above the
table, 80 mm apart along the camera's x axis (640x480, grey).

    .venv/bin/python -m bench.coldstart [--repeats 3] [--max-disparity 80] [--threads N]
        [--options '{"subpixel": "none"}'] [--markdown] [--variant NAME=SRC ...]
"""

from __future__ import annotations

import argparse
import json
import math
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from bench.harness import child_command, child_env

HEIGHT_M = 0.55
BASELINE_M = 0.08  # the demo's default baseline
WARM_CALLS = 3


def render_pair(path: Path) -> None:
    """The mock demo's scene from two poses ``BASELINE_M`` apart, saved as grey images."""
    import cv2

    from armstereo.mount import CameraMount
    from armstereo.transforms import make_T, rot_x, rot_z
    from drivers.mock.scene import SCENE_CENTER, default_table_scene

    mount = CameraMount.load()
    scene = default_table_scene()
    T0 = make_T(rot_x(math.pi) @ rot_z(0.05), [SCENE_CENTER[0], SCENE_CENTER[1], HEIGHT_M])
    T1 = T0.copy()
    T1[:3, 3] += T0[:3, :3] @ np.array([BASELINE_M, 0.0, 0.0])
    grey = []
    for T in (T0, T1):
        img, _ = scene.render(T, mount.intrinsics)
        grey.append(cv2.cvtColor(img, cv2.COLOR_BGR2GRAY) if img.ndim == 3 else img)
    np.savez(path, left=grey[0], right=grey[1])


def child(pair_path: str, max_disparity: int, threads: int | None, options: dict) -> dict:
    """One process: import, first call, warm calls; compile events of the first call."""
    t0, c0 = time.perf_counter(), time.process_time()
    from numba.core import event

    from armstereo.reconstruct.stereo import birchfield

    out = {"import_wall": time.perf_counter() - t0, "import_cpu": time.process_time() - c0}
    pair = np.load(pair_path)
    left, right = pair["left"], pair["right"]

    def call() -> tuple[float, float]:
        t, c = time.perf_counter(), time.process_time()
        birchfield(left, right, max_disparity, threads=threads, **options)
        return time.perf_counter() - t, time.process_time() - c

    with event.install_recorder("numba:compile") as rec:
        out["first_wall"], out["first_cpu"] = call()
    warm = [call() for _ in range(WARM_CALLS)]
    out["warm_wall"] = statistics.median(w for w, _ in warm)
    out["warm_cpu"] = statistics.median(c for _, c in warm)
    out["kernels"] = _per_kernel(rec.buffer)
    return out


def _per_kernel(buffer) -> list[dict]:
    """Inclusive and own wall time of each compiled (kernel, signature) from the events."""
    stack, done = [], []
    for stamp, ev in buffer:
        if ev.is_start:
            stack.append([ev.data["dispatcher"].py_func.__qualname__,
                          ev.data["dispatcher"].py_func.__module__.rsplit(".", 1)[-1],
                          stamp, 0.0])
        else:
            name, module, start, nested = stack.pop()
            total = stamp - start
            if stack:
                stack[-1][3] += total
            done.append({"kernel": f"{module}.{name}", "inclusive": total,
                         "own": total - nested, "top": not stack})
    return done


def run_child(pair_path: Path, cache: str, args, src: str | None) -> dict:
    # src: a copy of the source tree (its ``armstereo`` package) to measure instead
    env = child_env(dict(os.environ, NUMBA_CACHE_DIR=cache), src)
    cmd = child_command("bench.coldstart", "--child", str(pair_path), "--max-disparity",
                        str(args.max_disparity), "--options", args.options)
    if args.threads:
        cmd += ["--threads", str(args.threads)]
    done = subprocess.run(cmd, env=env, capture_output=True, text=True, check=True)
    return json.loads(done.stdout.strip().splitlines()[-1])


def summarize(cold: list[dict], cached: list[dict]) -> dict:
    med = statistics.median
    s = {}
    for key in ("wall", "cpu"):
        s[f"compile_{key}"] = med(r[f"first_{key}"] - r[f"warm_{key}"] for r in cold)
        s[f"load_{key}"] = med(r[f"first_{key}"] - r[f"warm_{key}"] for r in cached)
        s[f"warm_{key}"] = med([r[f"warm_{key}"] for r in cold + cached])
        s[f"import_{key}"] = med(r[f"import_{key}"] for r in cold)
        s[f"compile_{key}_min"] = min(r[f"first_{key}"] - r[f"warm_{key}"] for r in cold)
    per: dict[str, list[tuple[float, float]]] = {}
    for r in cold:
        seen: dict[str, list[float]] = {}
        for k in r["kernels"]:
            acc = seen.setdefault(k["kernel"], [0.0, 0.0, 0])
            acc[0] += k["inclusive"] if k["top"] else 0.0
            acc[1] += k["own"]
            acc[2] += 1
        for name, (inc, own, n) in seen.items():
            per.setdefault(name, []).append((inc, own, n))
    s["kernels"] = sorted(((name, med(v[0] for v in vals), med(v[1] for v in vals),
                            vals[0][2]) for name, vals in per.items()),
                          key=lambda row: -row[2])
    s["events_total"] = med(sum(k["inclusive"] for k in r["kernels"] if k["top"])
                            for r in cold)
    return s


def report(s: dict, markdown: bool) -> None:
    print(f"compile (first call - warm): {s['compile_wall']:.2f} s wall, "
          f"{s['compile_cpu']:.2f} s CPU (least {s['compile_cpu_min']:.2f} s); "
          f"numba:compile events {s['events_total']:.2f} s")
    print(f"cached process (load):       {s['load_wall']:.3f} s wall, {s['load_cpu']:.3f} s CPU")
    print(f"warm call:                   {s['warm_wall'] * 1000:.0f} ms wall, "
          f"{s['warm_cpu'] * 1000:.0f} ms CPU")
    print(f"import armstereo.reconstruct.stereo: {s['import_wall']:.2f} s wall")
    sep = "|" if markdown else " "
    print(f"{sep} kernel (signatures) {sep} top-level s {sep} own s {sep}" if markdown else
          "kernel (signatures)                         top-level s   own s")
    if markdown:
        print("|---|---|---|")
    for name, inc, own, n in s["kernels"]:
        label = f"{name} ({n})"
        if markdown:
            print(f"| {label} | {inc:.2f} | {own:.2f} |")
        else:
            print(f"{label:44s} {inc:10.2f} {own:7.2f}")


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--max-disparity", type=int, default=80)
    p.add_argument("--threads", type=int, default=None)
    p.add_argument("--options", default="{}", help="JSON of extra birchfield() options")
    p.add_argument("--markdown", action="store_true")
    p.add_argument("--variant", action="append", default=[], metavar="NAME=SRC",
                   help="measure the armstereo package under SRC (a copy of the source tree) "
                        "as NAME; repeat to compare variants side by side")
    p.add_argument("--child", metavar="PAIR", help=argparse.SUPPRESS)
    args = p.parse_args(argv)
    if args.child:
        res = child(args.child, args.max_disparity, args.threads, json.loads(args.options))
        print(json.dumps(res))
        return 0
    variants = dict(v.split("=", 1) for v in args.variant) or {"this checkout": None}
    runs = {name: ([], []) for name in variants}
    load = []
    with tempfile.TemporaryDirectory(prefix="coldstart_") as tmp:
        pair_path = Path(tmp) / "pair.npz"
        render_pair(pair_path)
        for i in range(args.repeats):  # variants interleaved: the same load for each
            for name, src in variants.items():
                cache = tempfile.mkdtemp(dir=tmp)
                cold, cached = runs[name]
                load.append(os.getloadavg()[0])
                cold.append(run_child(pair_path, cache, args, src))
                cached.append(run_child(pair_path, cache, args, src))
                print(f"repeat {i + 1} {name}: compile "
                      f"{cold[-1]['first_cpu'] - cold[-1]['warm_cpu']:.2f} s CPU, warm "
                      f"{cold[-1]['warm_wall'] * 1000:.0f} ms", file=sys.stderr)
    print(f"load average {min(load):.1f}-{max(load):.1f} on {os.cpu_count()} cores; "
          f"{args.repeats} repeats, medians; max_disparity {args.max_disparity}, threads "
          f"{args.threads or 'default'}, options {args.options}")
    for name, (cold, cached) in runs.items():
        print(f"\n## {name}\n")
        report(summarize(cold, cached), args.markdown)
    return 0


if __name__ == "__main__":
    sys.exit(main())
