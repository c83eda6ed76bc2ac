"""Baseline planning agrees with dZ = Z^2 dd / (f b) on hand-computed cases."""

import json

import pytest

from armstereo.apps.baseline import depth_error, overlap, recommend_baseline
from armstereo.cli.main import main
from armstereo.errors import ConfigError


def test_depth_error_formula_hand_case():
    # Z = 1 m, dd = 1 px, f = 500 px, b = 0.1 m -> 1 / 50 = 0.02 m
    assert depth_error(1.0, 500.0, 0.1, 1.0) == pytest.approx(0.02)
    assert overlap(1.0, 500.0, 0.1, 640) == pytest.approx(1 - 50 / 640)


def test_plan_hand_computed():
    # far = 2 m, dd = 0.25 px, f = 600 px, accuracy 5 mm -> b_min = 4 * 0.25 / 3 = 0.3333 m
    # budget: 256 / (600 * (1/1 - 1/2)) = 0.8533 m; overlap at 1 m: 0.4 * 640 / 600 = 0.4267 m
    p = recommend_baseline(1.0, 2.0, 0.005, focal_px=600, extent_px=640, max_disparity=256)
    assert p.min_baseline_m == pytest.approx(1 / 3)
    assert p.max_baseline_m == pytest.approx(0.4 * 640 / 600)
    assert p.limited_by == "overlap"
    assert p.baseline_m == pytest.approx(0.334)
    assert p.accuracy_far_m == pytest.approx(4 * 0.25 / (600 * 0.334))
    assert p.accuracy_far_m <= 0.005
    assert p.disparity_near_px == pytest.approx(600 * 0.334)
    assert p.disparity_range_px == pytest.approx(600 * 0.334 * 0.5)


def test_plan_infeasible_names_the_conflict():
    with pytest.raises(ConfigError, match="disparity budget"):
        recommend_baseline(0.5, 2.0, 0.0005, focal_px=600, extent_px=640, max_disparity=64)
    with pytest.raises(ConfigError, match="near"):
        recommend_baseline(2.0, 1.0, 0.01, focal_px=600, extent_px=640)


def test_plan_cli_json_and_text(capsys):
    assert main(["plan", "--near", "0.4", "--far", "0.8", "--depth-accuracy", "0.003",
                 "--max-disparity", "128", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    # default mount: f = 600 px; b_min = 0.64 * 0.25 / (600 * 0.003) = 0.08889 m
    assert out["min_baseline_m"] == pytest.approx(0.64 * 0.25 / 1.8)
    assert out["baseline_m"] == pytest.approx(0.089)
    assert main(["plan", "--near", "0.4", "--far", "0.8", "--depth-accuracy", "0.01"]) == 0
    assert "recommended baseline" in capsys.readouterr().out
    assert main(["plan", "--near", "0.4", "--far", "0.8", "--depth-accuracy", "0"]) == 2
    assert "error" in capsys.readouterr().err
