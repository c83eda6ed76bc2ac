"""Object measurement: footprint rectangles, flat and curved tops, sphere fits, outliers."""

from __future__ import annotations

import math

import numpy as np
import pytest

from armstereo.scene.objects import (
    fit_sphere,
    footprint_rectangle,
    measure_shape,
    outlier_mask,
    top_height,
)


def _top_face(L, W, H, yaw_deg=0.0, spacing=0.001, noise=0.0, seed=0, centre=(0.0, 0.0)):
    g = np.arange(-0.3, 0.3, spacing)
    x, y = np.meshgrid(g, g)
    a = math.radians(yaw_deg)
    u = np.cos(a) * x.ravel() + np.sin(a) * y.ravel()
    v = -np.sin(a) * x.ravel() + np.cos(a) * y.ravel()
    inside = (np.abs(u) <= L / 2) & (np.abs(v) <= W / 2)
    rng = np.random.default_rng(seed)
    h = H + rng.normal(0, noise, inside.sum())
    return np.column_stack([x.ravel()[inside] + centre[0], y.ravel()[inside] + centre[1], h])


def _cap(r, spacing=0.001, noise=0.0, seed=0, lost_rim=0.0):
    """The part of a resting sphere seen from above; ``lost_rim`` m of its rim missing."""
    g = np.arange(-r, r, spacing)
    x, y = np.meshgrid(g, g)
    rho = np.hypot(x.ravel(), y.ravel())
    inside = rho < r - lost_rim
    h = r + np.sqrt(r * r - rho[inside] ** 2) + np.random.default_rng(seed).normal(
        0, noise, inside.sum())
    return np.column_stack([x.ravel()[inside], y.ravel()[inside], h])


@pytest.mark.parametrize("yaw", [0.0, 17.0, -63.0, 90.0])
def test_rotated_box_footprint_size_centre_and_angle(yaw):
    p = _top_face(0.12, 0.08, 0.1, yaw, centre=(0.02, -0.03))
    (cu, cv), L, W, angle = footprint_rectangle(p[:, :2])
    assert (L, W) == pytest.approx((0.12, 0.08), abs=0.0015)
    assert (cu, cv) == pytest.approx((0.02, -0.03), abs=0.001)  # one point spacing
    d = (math.degrees(angle) - yaw + 90) % 180 - 90
    assert abs(d) < 0.5 and -90 < math.degrees(angle) <= 90


def test_flat_top_is_the_peak_median_despite_mismatches_above():
    p = _top_face(0.1, 0.1, 0.06, noise=0.0004)
    rng = np.random.default_rng(1)
    spikes = rng.uniform(0.061, 0.075, int(0.02 * len(p)))  # 2 % scattered above the edge
    h, kind = top_height(np.r_[p[:, 2], spikes])
    assert kind == "flat" and h == pytest.approx(0.06, abs=0.0002)
    assert np.percentile(np.r_[p[:, 2], spikes], 99.5) > 0.062  # what a percentile would say


def test_curved_top_is_a_high_percentile():
    cap = _cap(0.04)
    h, kind = top_height(cap[:, 2])
    assert kind == "curved" and h == pytest.approx(0.08, abs=0.0005)


def test_sphere_fit_recovers_a_ball_from_a_cap_without_its_rim():
    cap = _cap(0.045, noise=0.0003, lost_rim=0.008)  # stereo loses the steep rim
    (cu, cv, ch), r = fit_sphere(cap)
    assert r == pytest.approx(0.045, abs=0.0005)
    assert (cu, cv, ch) == pytest.approx((0.0, 0.0, 0.045), abs=0.0005)
    shape = measure_shape(cap, noise_m=0.0003)
    assert shape.model == "sphere" and shape.top == "curved"
    assert shape.length == pytest.approx(0.09, abs=0.001)
    assert shape.measured_width < 0.08  # what the footprint rectangle alone would say


def test_box_and_disc_tops_are_not_spheres():
    assert measure_shape(_top_face(0.1, 0.06, 0.04)).model == "box"
    g = np.arange(-0.05, 0.05, 0.001)
    x, y = np.meshgrid(g, g)
    disc = np.hypot(x, y).ravel() <= 0.05
    puck = np.column_stack([x.ravel()[disc], y.ravel()[disc], np.full(disc.sum(), 0.04)])
    shape = measure_shape(puck)
    assert shape.model == "box" and shape.top == "flat"
    assert shape.length == pytest.approx(0.1, abs=0.0015)
    assert fit_sphere(np.zeros((10, 3))) is None


def test_outlier_filter_drops_a_sparse_streak_but_keeps_a_clean_rim():
    face = _top_face(0.1, 0.06, 0.05)
    keep = outlier_mask(face)
    assert keep.all()  # a clean, regular face keeps its rim
    streak = np.column_stack([np.linspace(0.051, 0.07, 12), np.zeros(12), np.full(12, 0.05)])
    pts = np.vstack([face, streak])
    keep = outlier_mask(pts)
    assert not keep[-10:].any() and keep[:len(face)].mean() > 0.999
    _, L, _, _ = footprint_rectangle(pts[keep, :2])
    assert L == pytest.approx(0.1, abs=0.0015)
