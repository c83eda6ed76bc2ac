"""The benchmarks' shared harness, and the rules every bench script keeps: no path edits, no
imports from tests/, no script loaded from a file path (they import each other as ``bench.*``)."""

from __future__ import annotations

import ast
import itertools
import sys

import numpy as np
import pytest

from bench import harness
from tests.support import ROOT

SCRIPTS = sorted((ROOT / "bench").glob("*.py"))
# Runs inside an Open3D venv of its own (bench/fusion.py --open3d PYTHON), which has no armstereo.
STANDALONE = {"open3d_peer.py", "__init__.py"}


def test_timed_returns_the_result_and_the_clock_difference():
    ticks = itertools.count()
    out, dt = harness.timed(lambda a, b=0: a + b, 2, b=3, clock=lambda: float(next(ticks)))
    assert (out, dt) == (5, 1.0)


def test_median_time_skips_the_warm_up_and_keeps_the_last_result():
    calls = []
    clock = iter([0.0, 5.0, 10.0, 11.0, 20.0, 23.0]).__next__
    t, out = harness.median_time(lambda: calls.append(1) or len(calls), 3, warmup=1,
                                 clock=clock)
    assert len(calls) == 4 and out == 4
    assert t == 3.0  # rounds of 5, 1 and 3 s


def test_interleaved_runs_the_peers_in_turn():
    order = []
    got = harness.interleaved({"a": lambda: order.append("a") or "A",
                               "b": lambda: order.append("b") or "B"}, 2, warmup=1)
    assert order == ["a", "b"] * 3
    assert got["a"][1] == "A" and got["b"][1] == "B" and got["a"][0] >= 0


def test_best_time_is_the_least():
    clock = iter([0.0, 4.0, 4.0, 5.0, 5.0, 7.0]).__next__
    assert harness.best_time(lambda: None, 3, clock=clock) == 1.0


def test_write_report_prints_and_writes_into_a_new_folder(tmp_path, capsys):
    out = tmp_path / "new" / "r.md"
    harness.write_report("# r\n", out)
    assert out.read_text() == "# r\n" and capsys.readouterr().out == "# r\n\n"
    harness.write_report("x", None, echo=False)
    assert capsys.readouterr().out == ""


def test_child_env_puts_another_tree_first_then_this_one(tmp_path):
    env = harness.child_env({"PYTHONPATH": "/elsewhere"}, src=tmp_path)
    assert env["PYTHONPATH"].split(":") == [str(tmp_path.resolve()), str(ROOT), "/elsewhere"]
    assert harness.child_command("bench.x", "--a")[1:] == ["-P", "-m", "bench.x", "--a"]
    assert harness.child_command("bench.x")[0] == sys.executable


def test_the_middlebury_cases_load_with_an_sgbm_window():
    (case,) = harness.middlebury_cases(("tsukuba",))
    assert case.left.shape == case.right.shape and case.gt.shape == case.left.shape[:2]
    assert (case.max_disparity + 1) % 16 == 0 and case.mask.dtype == bool


def test_a_rendered_plane_has_its_disparity_everywhere():
    left, right, gt, nonocc = harness.render([harness.Surface(8.0, 0.0, 0.0, -1e9, 1e9, -1e9,
                                                              1e9)], 64, 32, supersample=1)
    assert left.shape == (32, 64, 3) and np.allclose(gt, 8.0)
    assert nonocc[:, 10:].all() and not nonocc[:, :7].any()


@pytest.mark.parametrize("path", SCRIPTS, ids=lambda p: p.name)
def test_bench_scripts_keep_the_rules(path):
    tree = ast.parse(path.read_text())
    imports = [n.module for n in ast.walk(tree) if isinstance(n, ast.ImportFrom) and n.module]
    imports += [a.name for n in ast.walk(tree) if isinstance(n, ast.Import) for a in n.names]
    assert not [m for m in imports if m == "tests" or m.startswith("tests.")]
    text = path.read_text()
    assert "sys.path" not in text and "spec_from_file_location" not in text
    if path.name not in STANDALONE | {"harness.py"}:
        assert any(m == "bench.harness" or m.startswith("bench.") for m in imports), \
            f"{path.name} does not use bench.harness"
