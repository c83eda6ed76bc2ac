"""The motion study: repeatable, and its numbers say what the geometry predicts."""

from __future__ import annotations

import numpy as np
import pytest

from armstereo.epipolar.study import StudyConfig, markdown_table, run_study
from armstereo.epipolar.study_scenes import MOTIONS, two_views

CONFIG = StudyConfig(trials=2, points=60, methods=("8point", "magsac", "gold"))


@pytest.fixture(scope="module")
def rows():
    return run_study(CONFIG)


def cell(rows, scene, motion, noise, method):
    return next(r for r in rows if (r.scene, r.motion, r.noise_px, r.method)
                == (scene, motion, noise, method))


def test_same_seed_same_numbers(rows):
    again = run_study(CONFIG)
    for a, b in zip(rows, again, strict=True):
        assert a.epipolar_mean_px == b.epipolar_mean_px or (np.isnan(a.epipolar_mean_px)
                                                            and np.isnan(b.epipolar_mean_px))


@pytest.mark.parametrize("motion", ["lateral", "forward", "general"])
def test_perfect_points_give_the_exact_geometry(rows, motion):
    for method in CONFIG.methods:
        assert cell(rows, "cloud", motion, 0.0, method).truth_mean_px < 1e-3


def test_noise_costs_a_fraction_of_its_size(rows):
    r = cell(rows, "cube", "general", CONFIG.noise_px, "gold")
    assert 0.0 < r.truth_mean_px < CONFIG.noise_px
    assert r.epipolar_median_px == pytest.approx(0.67 * CONFIG.noise_px, rel=0.35)


def test_rotation_only_is_flagged_and_has_no_truth(rows):
    for scene in ("cube", "cloud"):
        r = cell(rows, scene, "rotation_only", CONFIG.noise_px, "magsac")
        assert r.flagged == 1.0 and np.isnan(r.truth_mean_px)
        assert cell(rows, scene, "lateral", CONFIG.noise_px, "magsac").flagged == 0.0
    # perfect rotation-only points leave the 8-point system without a unique solution
    assert cell(rows, "cloud", "rotation_only", 0.0, "8point").failed == CONFIG.trials


def test_markdown_table_has_a_row_per_scene_and_motion(rows):
    lines = markdown_table(rows, CONFIG.noise_px, "truth_mean_px")
    assert lines[0] == "| scene | motion | 8point | magsac | gold |"
    assert len(lines) == 2 + 2 * len(MOTIONS)


def test_scenes_are_seen_by_both_cameras():
    v = two_views("cube", "forward", 50, np.random.default_rng(1))
    assert v.x1.shape == v.x2.shape == (50, 2)
    assert np.all((v.x2 >= 0) & (v.x2 <= [639, 479]))
