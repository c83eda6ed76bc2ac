"""Calibrated-looking DH tables for simulated arms: a seeded, physically plausible factory
calibration of a UR model.

A real arm's joint axes are tilted and shifted from the drawing by fractions of a millimetre
and milliradians, and its encoders' zeros are off by about a milliradian. The controller's
calibrated DH table is those real axes written in DH form. This module does the same: it
perturbs the nominal axes (seeded, normally distributed), then rebuilds the DH table from the
perturbed axis lines (:func:`dh_from_axes`, the textbook common-normal construction). Nearly
parallel axes then give what real tables show (``d`` of joints 2-4 of hundreds of metres with
opposite signs, ``theta`` of whole radians), and the FK is a few millimetres and a few tenths of
a degree from nominal, like the public calibrations of real UR arms (1-8 mm, 0.3-1.3 deg at the
flange).
"""

from __future__ import annotations

import numpy as np

from armstereo.robot.dh import (
    CALIBRATION_LINEARISED,
    N_JOINTS,
    DHTable,
    frames,
    nominal_table,
)
from armstereo.transforms import rot_x, rot_y

SOURCE_SYNTHETIC = "synthetic"
# One standard deviation of each error, per joint.
AXIS_TILT_RAD = 1.7e-3     # direction of joint axes 2..6
AXIS_SHIFT_M = 0.4e-3      # position of joint axes 2..6
ZERO_OFFSET_RAD = 1.0e-3   # encoder zero of each joint
FLANGE_SHIFT_M = 0.3e-3    # flange along joint 6's axis
_PARALLEL_SIN = 1e-12      # below this sine two axes count as exactly parallel


def synthetic_calibration(model: str, seed: int) -> DHTable:
    """A calibrated DH table of ``model`` (a nominal model name): its axes perturbed with
    ``seed`` by the magnitudes above, written as a DH table (source "synthetic", calibration
    status 2, per-joint checksums drawn from the same seed)."""
    nominal = nominal_table(model)
    rng = np.random.default_rng(seed)
    F = frames(nominal, np.zeros(N_JOINTS))
    axes = []
    for k in range(1, N_JOINTS):  # DH frame k carries the axis of joint k + 1
        tilt = rng.normal(0.0, AXIS_TILT_RAD, 2)
        R = F[k, :3, :3] @ rot_x(tilt[0]) @ rot_y(tilt[1])
        point = F[k, :3, 3] + rng.normal(0.0, AXIS_SHIFT_M, 3)
        axes.append((point, R[:, 2], R[:, 0]))
    d6 = nominal.d[5] + rng.normal(0.0, FLANGE_SHIFT_M)
    theta, a, d, alpha = dh_from_axes(axes, d6)
    theta = theta + rng.normal(0.0, ZERO_OFFSET_RAD, N_JOINTS)
    checksums = tuple(int(c) for c in rng.integers(0, 2**32, N_JOINTS))
    return DHTable(model=nominal.model, theta=tuple(theta), a=tuple(a), d=tuple(d),
                   alpha=tuple(alpha), source=SOURCE_SYNTHETIC,
                   calibration_status=CALIBRATION_LINEARISED, checksums=checksums)


def dh_from_axes(axes: list[tuple[np.ndarray, np.ndarray, np.ndarray]],
                 d6: float) -> tuple[np.ndarray, ...]:
    """DH rows (theta, a, d, alpha; 4 arrays of 6) of an arm whose joint 1 axis is the ``base``
    z axis and whose joints 2..6 have the axes ``axes`` = 5 tuples (point (m), unit direction,
    reference x direction), all in ``base`` at q = 0. Frame 6 (the flange) lies ``d6`` along
    joint 6's axis with a6 = alpha6 = theta6 = 0.

    Each frame's x axis is the common normal from the previous axis, signed to agree with the
    reference direction; for exactly parallel axes the normal through the previous origin.
    """
    theta, a, d, alpha = (np.zeros(N_JOINTS) for _ in range(4))
    origin, x, z = np.zeros(3), np.array([1.0, 0.0, 0.0]), np.array([0.0, 0.0, 1.0])
    for k, (point, w, ref_x) in enumerate(axes):
        w = w / np.linalg.norm(w)
        n = np.cross(z, w)
        if np.linalg.norm(n) < _PARALLEL_SIN:
            s, foot_next = 0.0, point + ((origin - point) @ w) * w
            normal = foot_next - origin
        else:
            s, t = _closest_parameters(origin, z, point, w)
            foot_next, normal = point + t * w, n
        x_next = _unit_or(normal, ref_x - (ref_x @ z) * z)
        if x_next @ ref_x < 0:
            x_next = -x_next
        a[k] = (foot_next - (origin + s * z)) @ x_next
        d[k] = s
        theta[k] = np.arctan2(np.cross(x, x_next) @ z, x @ x_next)
        alpha[k] = np.arctan2(np.cross(z, w) @ x_next, z @ w)
        origin, x, z = foot_next, x_next, w
    d[N_JOINTS - 1] = d6
    return theta, a, d, alpha


def _closest_parameters(p: np.ndarray, u: np.ndarray, r: np.ndarray,
                        w: np.ndarray) -> tuple[float, float]:
    """Parameters s, t of the closest points p + s u and r + t w of two skew lines (unit u,
    w), in the cross-product form: for the nearly parallel axes of a UR arm the dot-product
    form (dividing by 1 - cos^2) would lose most digits to cancellation."""
    n = np.cross(u, w)
    den = n @ n
    delta = r - p
    return float(np.cross(delta, w) @ n / den), float(np.cross(delta, u) @ n / den)


def _unit_or(v: np.ndarray, fallback: np.ndarray) -> np.ndarray:
    norm = np.linalg.norm(v)
    if norm < _PARALLEL_SIN:
        v, norm = fallback, np.linalg.norm(fallback)
    return v / norm
