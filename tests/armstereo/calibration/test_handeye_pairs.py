"""The pairwise closed forms: OpenCV's five methods on every pair, and pairs left out."""

from __future__ import annotations

import numpy as np
import pytest

from armstereo.calibration.handeye import METHODS, closed_form_all, motion_pairs, solve_hand_eye
from armstereo.calibration.handeye_pairs import PairData, solve_pairs
from armstereo.calibration.poses import exp6, pose_difference
from armstereo.transforms import invert

X_TRUE = exp6([0.1, -0.2, 0.3, 0.02, 0.05, 0.1])
B_TRUE = exp6([0.3, 0.1, -0.2, 0.5, 0.1, 0.3])


def _views(n: int, spread: float, seed: int, noise: float = 1e-3):
    rng = np.random.default_rng(seed)
    F = [exp6(np.r_[rng.normal(size=3) * spread, rng.normal(size=3) * 0.2]) for _ in range(n)]
    C = [invert(f @ X_TRUE) @ B_TRUE @ exp6(rng.normal(size=6) * noise) for f in F]
    return F, C


@pytest.mark.parametrize("method", list(METHODS))
def test_every_pair_with_unit_weights_is_opencvs_method(method):
    F, C = _views(8, 0.25, 3)  # every relative rotation under 90 deg: one quaternion branch
    pairs = motion_pairs(F, C)
    A, B = np.array([p.A for p in pairs]), np.array([p.B for p in pairs])
    ours = solve_pairs(method, A, B, np.ones(len(pairs)))
    # Tsai: OpenCV's linear solve differs from numpy's in the last digits of a 3x3 system
    tol = 1e-4 if method == "tsai" else 1e-9
    np.testing.assert_allclose(ours, solve_hand_eye(F, C, method), atol=tol)
    data = PairData.of(A, B)
    np.testing.assert_allclose(solve_pairs(method, None, None, np.ones(len(pairs)), data=data),
                               ours, atol=1e-12)


def test_bad_pairs_are_left_out_without_dropping_their_views():
    """Two views a degree apart: OpenCV has to drop one of them; the pairwise solution keeps
    both views and only loses their one useless pair."""
    F, C = _views(7, 0.4, 5, noise=2e-4)
    F.append(F[2] @ exp6([0.0, 0.017, 0.0, 0.01, 0.0, 0.0]))
    C.append(invert(F[-1] @ X_TRUE) @ B_TRUE)
    pairs = motion_pairs(F, C)
    assert sum(not p.usable for p in pairs) >= 1
    out = closed_form_all(F, C, pairs)
    assert set(out) == set(METHODS)
    for est in out.values():
        dt, dr = pose_difference(est.T_flange_camera, X_TRUE)
        assert dt < 0.002 and dr < 0.1


def test_too_few_pairs_are_refused():
    F, C = _views(3, 0.4, 1)
    pairs = motion_pairs(F, C)
    with pytest.raises(ValueError, match="two motion pairs"):
        solve_pairs("park", np.array([pairs[0].A]), np.array([pairs[0].B]), np.ones(1))
    with pytest.raises(ValueError, match="unknown"):
        solve_pairs("magic", np.array([p.A for p in pairs]), np.array([p.B for p in pairs]),
                    np.ones(3))
