"""Every flag of every command, given a hostile value, ends with a documented exit code other
than 1, one line on stderr (never a traceback or "internal error") and no partial output.

The grid (command x flag x value) is built from the parser itself, so a new flag is fuzzed the
day it is added, and a new command fails here until it has a baseline command line below. CI
runs a seeded sample of the grid (``ARMSTEREO_FUZZ_SAMPLE`` cases, default 30, seed
``ARMSTEREO_FUZZ_SEED``); ``pytest -m fuzz`` runs all of it.
"""

from __future__ import annotations

import argparse
import os
import random
import shutil
from pathlib import Path

import numpy as np
import pytest

from armstereo.cli.main import build_parser, main
from armstereo.evaluation.scene_truth import SceneTruth
from armstereo.io.ply import write_ply
from armstereo.scene import synthetic as synth
from tests.support import DATA, MIDDLEBURY, SAMPLE_RECORDING

DOCUMENTED_EXIT_CODES = {0, 2, 3, 4, 5, 6, 130}  # docs/commands.md §2 (and the README)
HOSTILE = ["0", "-1", "nan", "inf", "1e308", "", "abc", "{missing}", "{dir}", "{text}"]
TSUKUBA = MIDDLEBURY / "tsukuba"
TEMPLE = DATA / "temple_ring"

# A fast, valid command line per command; {out} is a fresh path the command may create.
BASELINES: dict[str, list[str]] = {
    "demo": ["demo", "--out", "{out}"],
    "capture": ["capture", "--out", "{out}.mcap"],
    "inspect": ["inspect", "{sample}"],
    "reconstruct": ["reconstruct", "{sample}", "--out", "{out}"],
    "stereo": ["stereo", str(TSUKUBA / "imL.png"), str(TSUKUBA / "imR.png"),
               "--max-disparity", "15", "--out", "{out}.pfm"],
    "eval": ["eval", str(TSUKUBA / "groundtruth.png"), str(TSUKUBA / "groundtruth.png"),
             "--gt-scale", "16", "--disp-scale", "16"],
    "plan": ["plan", "--near", "0.4", "--far", "0.8", "--depth-accuracy", "0.004"],
    "sweep": ["sweep", "--baselines", "0.05", "--distances", "1.0", "--out", "{out}"],
    "robot-info": ["robot-info", "--host", "127.0.0.1", "--timeout", "0.5"],
    "check": ["check", "{sample}"],
    "reconstruct-images": ["reconstruct-images", str(TEMPLE / "templeSR0008.png"),
                           str(TEMPLE / "templeSR0009.png"), "--out", "{out}"],
    "study": ["study", "epipolar", "--trials", "1", "--points", "20", "--out", "{out}"],
    "analyze": ["analyze", "{cloud}", "--out", "{out}"],
    "fuse": ["fuse", "{sample}", "--out", "{out}", "--voxel", "0.01"],
    "scan": ["scan", "--target=-0.45,-0.13,0.03", "--baseline", "0.06", "--views", "ring:1",
             "--out", "{out}.mcap"],
    "calibrate": ["calibrate", "--board", "chessboard:17x12:0.016", "--out", "{out}.toml",
                  "--dry-run"],
    "export": ["export", "{sample}", "--to", "ros2", "--out", "{out}"],
    "import": ["import", "{bag}", "--image-topic", "/camera/image", "--out", "{out}.mcap"],
}


def commands() -> dict[str, argparse.ArgumentParser]:
    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return dict(sub.choices)


def grid() -> list[tuple[str, str, str]]:
    """(command, flag or positional index, hostile value) for every value-taking argument."""
    cases = []
    for name, p in sorted(commands().items()):
        for action in p._actions:
            if action.nargs == 0 or isinstance(action, argparse._HelpAction):
                continue
            target = action.option_strings[0] if action.option_strings else f"#{action.dest}"
            cases += [(name, target, value) for value in HOSTILE]
    return cases


def sample(cases: list, n: int, seed: int) -> list:
    return random.Random(seed).sample(cases, min(n, len(cases)))


def test_every_command_has_a_baseline():
    assert set(commands()) == set(BASELINES), "add a fast baseline command line for new commands"


def argv_for(command: str, target: str, value: str, tmp: Path) -> tuple[list[str], Path | None]:
    """The baseline with ``target`` set to ``value``; returns it and the output it may make."""
    (tmp / "a_dir").mkdir(exist_ok=True)
    (tmp / "a.txt").write_text("not what you wanted\n")
    fill = {"{missing}": str(tmp / "missing.file"), "{dir}": str(tmp / "a_dir"),
            "{text}": str(tmp / "a.txt")}
    value = fill.get(value, value)
    out = tmp / "out"
    argv = [a.replace("{out}", str(out)).replace("{cloud}", str(_cloud(tmp)))
            .replace("{sample}", str(_sample(tmp))) for a in BASELINES[command]]
    argv = [str(_bag(tmp)) if a == "{bag}" else a for a in argv]
    if target.startswith("#"):
        positionals = [i for i, a in enumerate(argv[1:], 1)
                       if not a.startswith("-") and not argv[i - 1].startswith("--")]
        dests = [a.dest for a in commands()[command]._actions
                 if not a.option_strings and a.nargs != 0]
        argv[positionals[dests.index(target[1:])]] = value
    elif target in argv:
        argv[argv.index(target) + 1] = value
    else:
        argv += [target, value]
    watched = None if target == "--out" else _output(argv)
    return ["-q", *argv], watched


def _sample(tmp: Path) -> Path:
    """A copy of the sample recording: commands write their default outputs beside it."""
    path = tmp / "sample.mcap"
    if not path.exists():
        shutil.copyfile(SAMPLE_RECORDING, path)
    return path


def _bag(tmp: Path) -> Path:
    """The sample recording as a ROS 2 bag, for ``import``."""
    from armstereo.ros2.export import export_recording

    path = tmp / "sample_bag"
    if not path.exists():
        export_recording(_sample(tmp), path)
    return path


def _cloud(tmp: Path) -> Path:
    """A small table-top cloud (a table and one box) as PLY, for ``analyze``."""
    path = tmp / "cloud.ply"
    if not path.exists():
        scan = synth.scan(SceneTruth([synth.table(), synth.box("b", 0.0, 0.0, 0.1, 0.08, 0.06)]),
                          spacing=0.004)
        colors = scan.colors_bgr if scan.colors_bgr is not None else np.full(
            scan.points.shape, 128, np.uint8)
        write_ply(path, scan.points, colors, comment="frame base, metres")
    return path


def _output(argv: list[str]) -> Path | None:
    return Path(argv[argv.index("--out") + 1]) if "--out" in argv else None


def run_case(command, target, value, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)  # a value taken as a file name lands here, not in the checkout
    argv, out = argv_for(command, target, value, tmp_path)
    code = main(argv)
    err = [line for line in capsys.readouterr().err.splitlines() if line.strip()]
    where = f"armstereo {' '.join(argv)}"
    assert code in DOCUMENTED_EXIT_CODES, f"{where}: exit {code}; stderr {err}"
    assert not any("Traceback" in line or "internal error" in line for line in err), where
    if code != 0:
        assert len(err) == 1 and err[0].startswith("armstereo"), f"{where}: stderr {err}"
        assert out is None or not out.exists(), f"{where}: left {out} behind"


CASES = grid()
SEED = int(os.environ.get("ARMSTEREO_FUZZ_SEED", "20261130"))
SAMPLED = sample(CASES, int(os.environ.get("ARMSTEREO_FUZZ_SAMPLE", "30")), SEED)


@pytest.mark.parametrize("command,target,value", SAMPLED)
def test_hostile_values_sample(command, target, value, tmp_path, capsys, monkeypatch):
    run_case(command, target, value, tmp_path, capsys, monkeypatch)


@pytest.mark.fuzz
@pytest.mark.parametrize("command,target,value", [c for c in CASES if c not in SAMPLED])
def test_hostile_values_full_grid(command, target, value, tmp_path, capsys, monkeypatch):
    run_case(command, target, value, tmp_path, capsys, monkeypatch)
