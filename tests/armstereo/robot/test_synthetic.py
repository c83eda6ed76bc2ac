"""Synthetic factory calibrations (armstereo.robot.synthetic): a DH table rebuilt from
perturbed joint axes rotates about exactly those axes, and its FK is as far from nominal as
public calibrations of real UR arms are."""

from __future__ import annotations

import numpy as np
import pytest

from armstereo.robot.arm_model import MODEL_NAMES
from armstereo.robot.dh import (
    DHTable,
    fk,
    frames,
    nominal_table,
    pose_difference,
    workspace_joints,
)
from armstereo.robot.synthetic import dh_from_axes, synthetic_calibration
from armstereo.transforms import make_T, rotvec_to_matrix

# Flange error of five public real or test calibrations against nominal FK (median over the
# workspace): 0.9-4.2 mm and 0.20-0.90 deg; maxima 2.9-7.9 mm and 0.34-1.34 deg.
REAL_MEDIAN_MM = (0.9, 4.2)
REAL_MEDIAN_DEG = (0.20, 0.90)


def nominal_axes(model: str) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    F = frames(nominal_table(model), np.zeros(6))
    return [(F[k, :3, 3], F[k, :3, 2], F[k, :3, 0]) for k in range(1, 6)]


def perturbed_axes(model: str, seed: int, tilt: float, shift: float):
    rng = np.random.default_rng(seed)
    out = []
    for point, direction, ref in nominal_axes(model):
        R = rotvec_to_matrix(rng.normal(0, tilt, 3))
        out.append((point + rng.normal(0, shift, 3), R @ direction, R @ ref))
    return out


def screw_fk(axes_base, home: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Product of exponentials: joint i turns everything after it by q_i about its axis line
    (point p, unit direction w, in base at q = 0); ``home`` is the flange at q = 0."""
    T = np.eye(4)
    for (p, w), qi in zip(axes_base, q, strict=True):
        R = rotvec_to_matrix(w * qi)
        T = T @ make_T(R, p - R @ p)
    return T @ home


@pytest.mark.parametrize("model", MODEL_NAMES)
def test_nominal_axes_give_back_the_nominal_table(model):
    nominal = nominal_table(model)
    theta, a, d, alpha = dh_from_axes(nominal_axes(model), nominal.d[5])
    np.testing.assert_allclose(theta, 0.0, atol=1e-12)
    np.testing.assert_allclose(a, nominal.a, atol=1e-12)
    np.testing.assert_allclose(d, nominal.d, atol=1e-12)
    np.testing.assert_allclose(alpha, nominal.alpha, atol=1e-12)


@pytest.mark.parametrize("seed", range(4))
def test_table_from_axes_turns_about_those_axes(seed):
    axes = perturbed_axes("ur5e", seed, tilt=3e-3, shift=1e-3)
    theta, a, d, alpha = dh_from_axes(axes, 0.1)
    table = DHTable("ur5e", theta, a, d, alpha)
    F0 = frames(table, np.zeros(6))
    for k, (point, direction, _) in enumerate(axes, start=1):
        # DH frame k's z axis is the given axis of joint k + 1 (same line, same sense).
        z, origin = F0[k, :3, 2], F0[k, :3, 3]
        np.testing.assert_allclose(z, direction / np.linalg.norm(direction), atol=1e-12)
        off = origin - point  # may be kilometres along the axis: relative tolerance
        np.testing.assert_allclose(off - (off @ z) * z, 0.0,
                                   atol=1e-9 + 1e-12 * np.linalg.norm(off))
    lines = [(np.zeros(3), np.array([0.0, 0.0, 1.0]))]
    lines += [(p, w / np.linalg.norm(w)) for p, w, _ in axes]
    for q in np.random.default_rng(seed).uniform(-np.pi, np.pi, (20, 6)):
        np.testing.assert_allclose(fk(table, q), screw_fk(lines, F0[6], q), atol=1e-9)


def test_synthetic_calibrations_look_like_real_ones():
    q = workspace_joints(2000)
    medians_mm, medians_deg, far_d = [], [], 0
    for model in ("ur5e", "ur10e", "ur3e"):
        for seed in range(6):
            table = synthetic_calibration(model, seed)
            assert table.calibration_status == 2 and len(table.checksums) == 6
            lin, ang = pose_difference(fk(table, q), fk(nominal_table(model), q))
            medians_mm.append(np.median(lin) * 1000)
            medians_deg.append(np.degrees(np.median(ang)))
            assert 0.3 < medians_mm[-1] < 10.0 and lin.max() * 1000 < 25.0
            assert 0.1 < medians_deg[-1] < 1.5
            far_d += max(abs(v) for v in table.d[1:4]) > 1.0
    # Typical values sit inside the range of real calibrations ...
    assert REAL_MEDIAN_MM[0] < np.median(medians_mm) < REAL_MEDIAN_MM[1]
    assert REAL_MEDIAN_DEG[0] < np.median(medians_deg) < REAL_MEDIAN_DEG[1]
    # ... and so do the raw tables: nearly parallel axes put d far away, as on real arms.
    assert far_d >= 9


def test_synthetic_calibration_is_seeded():
    assert synthetic_calibration("ur5e", 4) == synthetic_calibration("ur5e", 4)
    assert synthetic_calibration("ur5e", 4).sha256 != synthetic_calibration("ur5e", 5).sha256
