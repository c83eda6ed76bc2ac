"""LMedS keeps the true inliers among 30 % gross outliers (issue 25; bench/results/lmeds.md)."""

from __future__ import annotations

import numpy as np

from armstereo.epipolar.fundamental import estimate_fundamental
from armstereo.epipolar.study_scenes import IMAGE_SIZE, MOTIONS, SCENES, two_views


def test_lmeds_keeps_85_percent_of_the_inliers_in_the_worst_of_10_trials():
    """The held-out study cell where the old LMedS (OpenCV's plus an 8-point refit) kept only
    71 % in one trial: every trial now keeps at least 85 % within the 1 px threshold."""
    rng = np.random.default_rng([2, SCENES.index("cloud"), MOTIONS.index("lateral"), 500])
    kept, outliers = [], []
    for trial in range(10):
        v = two_views("cloud", "lateral", 100, rng)
        x1 = v.x1 + rng.normal(0.0, 0.5, v.x1.shape)
        x2 = v.x2 + rng.normal(0.0, 0.5, v.x2.shape)
        bad = rng.random(len(x2)) < 0.3
        x2[bad] = rng.uniform((0, 0), IMAGE_SIZE, (int(bad.sum()), 2))
        _, mask = estimate_fundamental(x1, x2, "lmeds", seed=trial, allow_degenerate=True)
        kept.append(mask[~bad].mean())
        outliers.append(mask[bad].mean())
    assert min(kept) >= 0.85, kept
    assert np.mean(outliers) < 0.05  # not by letting the outliers in
