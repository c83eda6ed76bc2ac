"""Where the first ``birchfield()`` call's compile time goes: per kernel and per phase.

One fresh process (an empty, temporary ``NUMBA_CACHE_DIR`` unless ``--keep-cache``) makes
the first call of :func:`armstereo.reconstruct.stereo.birchfield` on the mock demo's pair
(:func:`coldstart.render_pair`) and records CPU time (``time.process_time``; the compile is
single-threaded):

- per kernel and signature (numba's ``numba:compile`` events), own time without the nested
  compiles of its callees;
- per phase, inside that: numba's passes (``numba:run_pass`` events: bytecode analysis,
  type inference, lowering to LLVM IR ...) and, timed by wrapping numba's code library, the
  LLVM work: IR parsing, per-function optimisation (``_optimize_functions``), the final
  module's optimisation after its callees are linked in (``_optimize_final_module``),
  machine-code generation (``_finalize_specific``: MCJIT's ``finalize_object``) and the
  on-disk cache. "cache: look up" outside any kernel is mostly numba's first refresh of its
  registries (it imports ``scipy.linalg`` for its BLAS check), paid once per process.

    .venv/bin/python -m bench.compile_phases [--repeats 3] [--max-disparity 80]
        [--options '{"subpixel": "none"}'] [--top 25]

Each repeat is its own process; the tables give the median over repeats (and the least).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from collections import defaultdict
from pathlib import Path

import numpy as np

from bench.harness import child_command, child_env

LLVM_PHASES = {  # (class path, method) -> phase name
    ("numba.core.codegen.CPUCodeLibrary", "_optimize_functions"): "llvm: function passes",
    ("numba.core.codegen.CPUCodeLibrary", "_optimize_final_module"): "llvm: final module opt",
    ("numba.core.codegen.JITCodeLibrary", "_finalize_specific"): "llvm: machine code",
    ("numba.core.codegen.CPUCodeLibrary", "add_ir_module"): "llvm: parse IR",
    ("numba.core.codegen.CPUCodeLibrary", "serialize_using_object_code"): "cache: emit object",
    ("numba.core.caching.Cache", "save_overload"): "cache: save",
    ("numba.core.caching.Cache", "load_overload"): "cache: look up",
}


class _Clock:
    """CPU time attributed to the innermost open (kernel, phase); nested spans are excluded
    from their parents' own time."""

    def __init__(self):
        self.stack = [["(outside)", "python", time.process_time()]]
        self.own = defaultdict(float)  # (kernel, phase) -> s

    def _charge(self):
        now = time.process_time()
        top = self.stack[-1]
        self.own[(top[0], top[1])] += now - top[2]
        top[2] = now
        return now

    def push(self, kernel: str | None, phase: str):
        now = self._charge()
        self.stack.append([kernel or self.stack[-1][0], phase, now])

    def pop(self):
        self._charge()
        self.stack.pop()
        self.stack[-1][2] = time.process_time()


def _install(clock: _Clock) -> None:
    import importlib

    from numba.core import event

    class Listener(event.Listener):
        def on_start(self, ev):
            if ev.kind == "numba:compile":
                f = ev.data["dispatcher"].py_func
                sig = ev.data.get("args")
                clock.push(f"{f.__module__.rsplit('.', 1)[-1]}.{f.__qualname__}", "python")
                clock.stack[-1].append(str(sig))
            else:
                clock.push(None, "pass: " + ev.data["name"])

        def on_end(self, ev):
            clock.pop()

    listener = Listener()
    event.register("numba:compile", listener)
    event.register("numba:run_pass", listener)

    for (cls_path, meth), phase in LLVM_PHASES.items():
        mod, cls = cls_path.rsplit(".", 1)
        klass = getattr(importlib.import_module(mod), cls)
        orig = getattr(klass, meth)

        def wrapped(*a, _orig=orig, _phase=phase, **k):
            clock.push(None, _phase)
            try:
                return _orig(*a, **k)
            finally:
                clock.pop()

        setattr(klass, meth, wrapped)


def child(pair_path: str, max_disparity: int, options: dict) -> dict:
    clock = _Clock()
    _install(clock)
    from armstereo.reconstruct.stereo import birchfield

    pair = np.load(pair_path)
    c0 = time.process_time()
    clock.stack = [["(outside)", "python", c0]]
    clock.own.clear()
    birchfield(pair["left"], pair["right"], max_disparity, threads=1, **options)
    first = time.process_time() - c0
    c1 = time.process_time()
    birchfield(pair["left"], pair["right"], max_disparity, threads=1, **options)
    warm = time.process_time() - c1
    clock._charge()
    return {"first": first, "warm": warm,
            "own": [[k, p, s] for (k, p), s in clock.own.items()]}


def _phase_group(phase: str) -> str:
    """A phase without the kernel's name that numba's pass events append."""
    return phase.split(" [", 1)[0]


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--max-disparity", type=int, default=80)
    p.add_argument("--options", default="{}")
    p.add_argument("--top", type=int, default=25)
    p.add_argument("--child", help=argparse.SUPPRESS)
    args = p.parse_args(argv)
    if args.child:
        print(json.dumps(child(args.child, args.max_disparity, json.loads(args.options))))
        return 0
    from bench.coldstart import render_pair

    runs = []
    with tempfile.TemporaryDirectory(prefix="phases_") as tmp:
        pair = Path(tmp) / "pair.npz"
        render_pair(pair)
        for _ in range(args.repeats):
            env = child_env(dict(os.environ, NUMBA_CACHE_DIR=tempfile.mkdtemp(dir=tmp)))
            out = subprocess.run(child_command("bench.compile_phases", "--child", str(pair),
                                               "--max-disparity", str(args.max_disparity),
                                               "--options", args.options),
                                 env=env, capture_output=True, text=True, check=True)
            runs.append(json.loads(out.stdout.strip().splitlines()[-1]))
    med = statistics.median
    print(f"load average {os.getloadavg()[0]:.1f}; {args.repeats} fresh processes; CPU s, "
          f"median (least)")
    print(f"first call {med(r['first'] for r in runs):.2f} ({min(r['first'] for r in runs):.2f})"
          f", warm call {med(r['warm'] for r in runs):.3f}")
    group = _phase_group
    for title, key in (("phase", lambda k, ph: group(ph)), ("kernel", lambda k, ph: k),
                       ("kernel / phase", lambda k, ph: f"{k} / {group(ph)}")):
        tables = []
        for r in runs:
            t = defaultdict(float)
            for k, ph, s in r["own"]:
                t[key(k, ph)] += s
            tables.append(t)
        names = {n for t in tables for n in t}
        rows = sorted(((n, med(t.get(n, 0.0) for t in tables), min(t.get(n, 0.0)
                                                                   for t in tables))
                       for n in names), key=lambda row: -row[1])
        print(f"\n| {title} | CPU s median | least |\n|---|---|---|")
        for n, m, lo in rows[:args.top]:
            print(f"| {n} | {m:.2f} | {lo:.2f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
