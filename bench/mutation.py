"""Mutation testing of the safety- and accuracy-critical modules with cosmic-ray.

    python -m bench.mutation                       # every target, then the report
    python -m bench.mutation --target plan run     # some targets only (the report keeps the rest)
    python -m bench.mutation --sample 40 --seed 1  # at most 40 random mutants per accuracy target
    python -m bench.mutation --survivors           # re-test only the kept survivors (new tests)
    python -m bench.mutation --report-only         # rewrite the report (e.g. new explanations)
    python -m bench.mutation --list                # the targets, their functions and tests

Each mutant is a one-line change (a comparison, an arithmetic or boolean operator, a number,
a constant, a loop that never runs, an exception type); the target's own fast test subset runs
against it and the mutant is *killed* if a test fails. What survives is listed in the report,
with the explanation kept in bench/mutation_equivalent.toml where a survivor is equivalent (no
test can tell it from the original). Needs the ``mutation`` extra (``pip install -e
".[mutation]"``).

Safety targets (pre-flight checks, the capture loop, the drivers' stop paths) always run every
mutant; ``--sample`` only thins the accuracy targets. Each target's results are kept in
bench/results/mutation/<target>.json and bench/results/mutation.md is written from all of them.

The run works on a copy of the repository's tracked files in a temporary folder, so a crash or
Ctrl-C can never leave a mutated file in the working tree. It runs at low priority (nice 10)
and sequentially: on a 2-core machine shared with others, the full run takes hours (see the
report's timings); ``--sample`` gives a quick seeded estimate.
"""

from __future__ import annotations

import argparse
import ast
import json
import os
import random
import re
import shutil
import subprocess
import sys
import tempfile
import time
import tomllib
from dataclasses import dataclass
from pathlib import Path

from bench.harness import ROOT

REPORT = ROOT / "bench" / "results" / "mutation.md"
RESULTS = ROOT / "bench" / "results" / "mutation"
EQUIVALENT = ROOT / "bench" / "mutation_equivalent.toml"
NICENESS = 10
# A mutant whose tests take longer than this many times the unmutated run (at least
# MIN_TIMEOUT_S) hangs them, and counts as killed: a loop that never ends is caught.
TIMEOUT_FACTOR = 4
MIN_TIMEOUT_S = 60

# Replacements into operators the code never uses on these numbers (shifts, bit operations,
# powers, modulo, floor division) are always caught by any test that reaches the line and cost
# a test run each; removing ``@njit`` only makes a kernel slower. Everything else runs.
EXCLUDED_OPERATORS = [
    r"core/ReplaceBinaryOperator_\w+_(Pow|LShift|RShift|BitOr|BitAnd|BitXor|FloorDiv|Mod)$",
    r"core/ReplaceBinaryOperator_(Pow|LShift|RShift|BitOr|BitAnd|BitXor|FloorDiv|Mod)_\w+$",
    r"core/RemoveDecorator$",
]


@dataclass(frozen=True)
class Target:
    """A module, the definitions in it to mutate (None: all) and the tests that cover them."""

    name: str
    module: str
    tests: tuple[str, ...]
    definitions: tuple[str, ...] | None = None
    kind: str = "accuracy"  # "safety": every survivor must be killed or explained


TARGETS = [
    Target("plan", "armstereo/capture/plan.py",
           ("tests/armstereo/capture/test_plan.py",),
           ("parse_direction", "around", "contains", "ok", "require_ok", "require_checks", "steps",
            "plan_capture",
            "validate_settings", "_translated", "check_speed", "_check_direction",
            "check_motion", "check_start", "sample_path", "check_path", "_view_joints",
            "_check_travel", "_estimate_duration"),
           kind="safety"),
    Target("run", "armstereo/capture/run.py",
           ("tests/armstereo/capture/test_run.py", "tests/armstereo/capture/test_session.py"),
           ("run_capture", "_move", "_shoot", "_record_pair", "_stop_quietly", "_say"),
           kind="safety"),
    Target("session", "armstereo/capture/session.py",
           ("tests/armstereo/capture/test_session.py",
            "tests/armstereo/cli/test_capture_cmd.py"), kind="safety"),
    Target("mock-arm", "drivers/mock/arm.py",
           ("tests/drivers/mock/test_arm_stop.py", "tests/drivers/mock/test_arm.py",
            "tests/drivers/mock/test_profile.py", "tests/armstereo/capture/test_run.py"),
           ("stop", "close", "wait_until_steady", "_execute", "_fail", "_halted",
            "_require_link", "_require_ready", "_check_positive"), kind="safety"),
    Target("ur-arm", "drivers/ur/arm.py",
           ("tests/drivers/ur/test_arm.py", "tests/drivers/ur/test_arm_stop.py"),
           ("close", "move_linear", "move_joints", "wait_until_steady", "stop", "_move",
            "_await_motion", "_verify_reached", "_stop_quietly", "_quiet_call", "_check_link",
            "_raise_if_stopped", "_check_cap", "_check_timeout"), kind="safety"),
    Target("rectify", "armstereo/reconstruct/rectify.py",
           ("tests/armstereo/reconstruct/test_rectify_properties.py",
            "tests/armstereo/reconstruct/test_rectify.py")),
    Target("triangulate", "armstereo/reconstruct/triangulate.py",
           ("tests/armstereo/reconstruct/test_triangulate.py",)),
    Target("stereo", "armstereo/reconstruct/stereo.py",
           ("tests/armstereo/reconstruct/test_stereo_properties.py",
            "tests/armstereo/reconstruct/test_stereo.py",
            "tests/armstereo/reconstruct/test_stereo_robust.py"),
           ("birchfield", "_match", "compute_disparity", "disparity", "_kernel_params",
            "_check_exact_width")),
    Target("stereo-inputs", "armstereo/reconstruct/stereo_inputs.py",
           ("tests/armstereo/reconstruct/test_stereo.py",
            "tests/armstereo/reconstruct/test_stereo_properties.py"),
           ("grey", "prepare", "_checked_image", "check_range")),
    Target("stereo-options", "armstereo/reconstruct/stereo_options.py",
           ("tests/armstereo/reconstruct/test_stereo_options.py",
            "tests/armstereo/reconstruct/test_stereo.py"),
           ("__post_init__", "_check_rejections", "_check_prefilter", "_window", "_smoothing",
            "options_for", "with_keywords")),
    Target("rejection", "armstereo/reconstruct/rejection.py",
           ("tests/armstereo/reconstruct/test_stereo_robust.py",
            "tests/armstereo/reconstruct/test_stereo_properties.py"),
           ("reject_invalid_partners", "single_runs", "clip_to_window")),
]


LOGGERS = ("log", "logger", "logging")


def log_call_lines(path: Path) -> set[int]:
    """Lines of calls like ``log.debug(...)``: a mutant there changes only a log message, so
    it is not run (the report counts such mutants separately)."""
    lines: set[int] = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if (isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute)
                and isinstance(node.func.value, ast.Name) and node.func.value.id in LOGGERS):
            lines.update(range(node.lineno, node.end_lineno + 1))
    return lines


def check_definitions(target: Target) -> None:
    """Every definition a target names must exist in its module: after a rename the target
    would silently stop mutating the renamed code."""
    tree = ast.parse((ROOT / target.module).read_text())
    defined = {node.name for node in ast.walk(tree)
               if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef | ast.ClassDef)}
    missing = sorted(set(target.definitions or ()) - defined)
    if missing:
        raise SystemExit(f"{target.name}: {target.module} defines none of {', '.join(missing)}"
                         f" (renamed?); update TARGETS in bench/mutation.py")


def main(argv: list[str] | None = None) -> int:
    args = _parse(argv)
    targets = [t for t in TARGETS if not args.target or t.name in args.target]
    for target in targets:
        check_definitions(target)
    if args.list:
        for t in targets:
            print(f"{t.name} ({t.kind}): {t.module} [{', '.join(t.definitions or ['all'])}] "
                  f"<- {' '.join(t.tests)}")
        return 0
    if not args.report_only:
        RESULTS.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryDirectory(prefix="armstereo-mutation-") as tmp:
            copy = _copy_repository(Path(tmp) / "repo")
            _warm_up(copy)
            for target in targets:
                kept = RESULTS / f"{target.name}.json"
                if args.survivors:
                    if not kept.exists():
                        continue
                    result = _retest_survivors(copy, target, json.loads(kept.read_text()))
                else:
                    sample = args.sample if target.kind == "accuracy" else args.sample_safety
                    result = _run_target(copy, target, sample, args.seed)
                kept.write_text(json.dumps(result, indent=1))
                _write_report(REPORT)
    _write_report(REPORT)
    print(f"report: {REPORT.relative_to(ROOT)}")
    return 0


def _parse(argv):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--target", nargs="*", choices=[t.name for t in TARGETS])
    p.add_argument("--sample", type=int, default=None,
                   help="at most this many mutants per accuracy target, drawn with --seed")
    p.add_argument("--sample-safety", type=int, default=None,
                   help="also thin the safety targets to this many mutants (a quick look; the "
                        "goal there needs the full run)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--survivors", action="store_true",
                   help="re-test only the survivors of the kept results (after adding tests)")
    p.add_argument("--report-only", action="store_true",
                   help="only rewrite the report from the kept results")
    p.add_argument("--list", action="store_true", help="list the targets and stop")
    return p.parse_args(argv)


def _copy_repository(dest: Path) -> Path:
    """The tracked files (as in the working tree) in ``dest``."""
    files = subprocess.run(["git", "ls-files", "-z"], cwd=ROOT, check=True,
                           capture_output=True).stdout.decode().split("\0")
    for name in filter(None, files):
        src = ROOT / name
        if src.is_file():
            (dest / name).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(src, dest / name)
    return dest


def _test_command(target: Target) -> str:
    # -x: the first failing test kills the mutant; -p no:cacheprovider: nothing written.
    return " ".join([sys.executable, "-m", "pytest", "-x", "-q", "-p", "no:cacheprovider",
                     "-p", "no:randomly", *target.tests])


def _env() -> dict[str, str]:
    env = dict(os.environ)
    env["PYTHONPATH"] = ""  # the copy is the working directory: it shadows the installed tree
    env.pop("HYPOTHESIS_PROFILE", None)  # the repeatable profile: same examples every run
    return env


def _warm_up(copy: Path) -> None:
    """Compile the numba kernels in the copy once, so mutants do not each pay for it."""
    code = ("import numpy as np\nfrom armstereo.reconstruct.stereo import birchfield\n"
            "img = np.zeros((8, 24), np.uint8)\nbirchfield(img, img, 4)\n")
    subprocess.run(["nice", "-n", str(NICENESS), sys.executable, "-c", code], cwd=copy,
                   env=_env(), check=True)


def _baseline(copy: Path, target: Target) -> float:
    """Run the target's tests on the unmutated copy: they must pass (else every mutant would
    look killed); returns their wall time (s)."""
    started = time.monotonic()
    proc = subprocess.run(["nice", "-n", str(NICENESS), *_test_command(target).split()],
                          cwd=copy, env=_env(), capture_output=True, text=True)
    if proc.returncode != 0:
        raise SystemExit(f"{target.name}: the tests fail without any mutant:\n"
                         f"{proc.stdout[-3000:]}")
    return time.monotonic() - started


def _config(copy: Path, target: Target, timeout: float) -> Path:
    path = copy / f"mutation-{target.name}.toml"
    excluded = ", ".join(f"'{e}'" for e in EXCLUDED_OPERATORS)
    path.write_text(
        "[cosmic-ray]\n"
        f"module-path = \"{target.module}\"\n"
        f"timeout = {timeout:.0f}\n"
        "excluded-modules = []\n"
        f"test-command = \"{_test_command(target)}\"\n\n"
        "[cosmic-ray.distributor]\nname = \"local\"\n\n"
        f"[cosmic-ray.filters.operators-filter]\nexclude-operators = [{excluded}]\n")
    return path


def _cosmic_ray(copy: Path, *args: str) -> None:
    subprocess.run(["nice", "-n", str(NICENESS), sys.executable, "-m", "cosmic_ray.cli", *args],
                   cwd=copy, env=_env(), check=True)


def _retest_survivors(copy: Path, target: Target, kept: dict) -> dict:
    """Run the survivors of ``kept`` again (killed mutants stay killed while tests are only
    added) and mark those now killed."""
    # Matched on the operator and the source text, not the line number: a fix elsewhere in
    # the module may have moved the line since the kept run.
    survivors = {(r["operator"], _mutated_lines(r["diff"])[0]) for r in kept["rows"]
                 if not r["killed"]}
    if not survivors:
        return kept
    again = _run_target(copy, target, None, kept["seed"], only=survivors)
    killed_now = {(r["operator"], *_mutated_lines(r["diff"])) for r in again["rows"]
                  if r["killed"]}
    for row in kept["rows"]:
        if not row["killed"] and (row["operator"], *_mutated_lines(row["diff"])) in killed_now:
            row["killed"] = True
    kept["retested"] = f"{len(again['rows'])} survivors on {again['date']}"
    return kept


def _run_target(copy: Path, target: Target, sample: int | None, seed: int,
                only: set[tuple[str, str]] | None = None) -> dict:
    from cosmic_ray.work_db import WorkDB, use_db
    from cosmic_ray.work_item import TestOutcome, WorkerOutcome, WorkResult

    baseline = _baseline(copy, target)
    config = _config(copy, target, max(MIN_TIMEOUT_S, TIMEOUT_FACTOR * baseline))
    db = copy / f"mutation-{target.name}.sqlite"
    _cosmic_ray(copy, "init", str(config), str(db))
    excluded = re.compile("|".join(EXCLUDED_OPERATORS))
    logging_lines = log_call_lines(copy / target.module)
    source = (copy / target.module).read_text().splitlines()
    log_only = 0
    with use_db(str(db), WorkDB.Mode.open) as work:
        items = sorted(work.pending_work_items, key=lambda w: w.job_id)
        keep = []
        for item in items:
            m = item.mutations[0]
            wanted = target.definitions is None or m.definition_name in target.definitions
            if not wanted or excluded.match(m.operator_name):
                continue
            if m.start_pos[0] in logging_lines:
                log_only += 1
                continue
            if only is None or (m.operator_name, source[m.start_pos[0] - 1].strip()) in only:
                keep.append(item)
        if sample is not None and len(keep) > sample:
            keep = random.Random(f"{seed}:{target.name}").sample(keep, sample)
        kept = {item.job_id for item in keep}
        for item in items:
            if item.job_id not in kept:
                work.set_result(item.job_id, WorkResult(worker_outcome=WorkerOutcome.SKIPPED,
                                                        output="not selected"))
    started = time.monotonic()
    _cosmic_ray(copy, "exec", str(config), str(db))
    elapsed = time.monotonic() - started
    rows = []
    with use_db(str(db), WorkDB.Mode.open) as work:
        for item, result in work.completed_work_items:
            if result.worker_outcome == WorkerOutcome.SKIPPED:
                continue
            m = item.mutations[0]
            rows.append(dict(line=m.start_pos[0], operator=m.operator_name,
                             definition=m.definition_name or "",
                             killed=result.test_outcome != TestOutcome.SURVIVED,
                             diff=result.diff or ""))
    return dict(target=target.name, kind=target.kind, module=target.module,
                tests=list(target.tests), rows=sorted(rows, key=lambda r: (r["line"],
                                                                          r["operator"])),
                elapsed=elapsed, baseline_s=baseline, selected=len(keep), sample=sample,
                seed=seed,
                log_only=log_only, date=time.strftime("%Y-%m-%d"))


def _mutated_lines(diff: str) -> tuple[str, str]:
    """(original, mutated) source lines of a one-line diff, stripped."""
    minus = [line[1:].strip() for line in diff.splitlines()
             if line.startswith("-") and not line.startswith("---")]
    plus = [line[1:].strip() for line in diff.splitlines()
            if line.startswith("+") and not line.startswith("+++")]
    return " / ".join(minus), " / ".join(plus)


def _equivalents() -> list[dict]:
    if not EQUIVALENT.exists():
        return []
    return tomllib.loads(EQUIVALENT.read_text()).get("mutant", [])


def _explanation(module: str, diff: str, known: list[dict]) -> str | None:
    original, mutated = _mutated_lines(diff)
    for entry in known:
        if (entry["module"] == module and entry["original"] == original
                and entry["mutated"] == mutated):
            return entry["why"]
    return None


def _write_report(path: Path) -> None:
    known = _equivalents()
    order = [t.name for t in TARGETS]
    results = [json.loads((RESULTS / f"{name}.json").read_text()) for name in order
               if (RESULTS / f"{name}.json").exists()]
    lines = ["# Mutation testing", "",
             "Made by `python -m bench.mutation` (cosmic-ray; targets, the tests each one runs "
             "and the operators left out are in bench/mutation.py; equivalent mutants are "
             "explained in bench/mutation_equivalent.toml). Safety targets run every mutant; "
             "accuracy targets may run a seeded sample (column 'sample'). Mutants on log "
             "calls change only a message and are not run. Times are rough: a shared, loaded "
             "2-core machine, at nice 10.", "",
             "| target | kind | module | mutants run | sample | killed | survived: equivalent "
             "| survived: not explained | killed % (with equivalents) | log-only | time | date |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    details = []
    for res in results:
        rows = res["rows"]
        killed = sum(r["killed"] for r in rows)
        survivors = [r for r in rows if not r["killed"]]
        explained = [(r, _explanation(res["module"], r["diff"], known)) for r in survivors]
        n_eq = sum(why is not None for _, why in explained)
        share = (f"{100 * killed / len(rows):.1f} ({100 * (killed + n_eq) / len(rows):.1f})"
                 if rows else "-")
        sample = f"{res['sample']} (seed {res['seed']})" if res["sample"] else "all"
        lines.append(f"| {res['target']} | {res['kind']} | `{res['module']}` | {len(rows)} | "
                     f"{sample} | {killed} | {n_eq} | {len(survivors) - n_eq} | {share} | "
                     f"{res['log_only']} | {res['elapsed'] / 60:.0f} min | {res['date']}"
                     + (f"; re-tested {res['retested']}" if res.get("retested") else "") + " |")
        if survivors:
            details += [f"## {res['target']}: survivors", ""]
            for r, why in explained:
                original, mutated = _mutated_lines(r["diff"])
                verdict = f"equivalent: {' '.join(why.split())}" if why else "**not explained**"
                details += [f"- line {r['line']} in `{r['definition']}` ({r['operator']}): "
                            f"`{original}` -> `{mutated}`; {verdict}"]
            details.append("")
    path.write_text("\n".join(lines + [""] + details))


if __name__ == "__main__":
    sys.exit(main())
