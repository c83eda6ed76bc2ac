"""Support plane: exact on synthetic tables, level check against the expected up, bad input."""

from __future__ import annotations

import math

import numpy as np
import pytest

from armstereo.scene.errors import SceneError
from armstereo.scene.plane import fit_support_plane, plane_frame
from armstereo.scene.synthetic import box, default_truth, scan, table
from armstereo.transforms import make_T, rot_x


def _tilted(points: np.ndarray, deg: float) -> np.ndarray:
    return points @ rot_x(math.radians(deg)).T


def test_level_table_normal_height_and_rms():
    cloud = scan(default_truth(), spacing=0.002, noise=0.0005)
    plane = fit_support_plane(cloud.points + [0, 0, 0.7])
    assert plane.tilt_deg < 0.05
    assert plane.height_m == pytest.approx(0.7, abs=2e-4)
    assert plane.rms_m == pytest.approx(0.0005, rel=0.1)
    assert plane.normal[2] > 0.999
    assert plane.area_m2 == pytest.approx(0.5 * 0.4, rel=0.03)  # the table's seen extent


def test_gently_inclined_table_is_found_with_its_tilt():
    pts = _tilted(scan(default_truth(), spacing=0.002, noise=0.0003).points, 4.0)
    plane = fit_support_plane(pts)
    assert plane.tilt_deg == pytest.approx(4.0, abs=0.02)
    # plane coordinates: heights of the table points are ~0
    assert np.median(np.abs(plane.heights(pts))) < 0.001


def test_steep_table_is_refused_with_its_tilt_and_accepted_with_up():
    pts = _tilted(scan(default_truth(), spacing=0.002, noise=0.0003).points, 30.0)
    with pytest.raises(SceneError, match=r"tilted (29|30)\.\d deg.*--up"):
        fit_support_plane(pts)
    up = rot_x(math.radians(30.0)) @ np.array([0.0, 0.0, 1.0])
    plane = fit_support_plane(pts, up=up)
    assert plane.tilt_deg < 0.05


def test_a_bigger_wall_does_not_win_over_the_level_table():
    tab = scan(default_truth(), spacing=0.003).points
    wall = _tilted(scan(default_truth(), spacing=0.002).points, 90.0) + [0, 0.3, 0.2]
    plane = fit_support_plane(np.vstack([tab, wall]))
    assert len(wall) > len(tab)
    assert plane.tilt_deg < 0.1 and abs(plane.height_m) < 1e-3


def test_a_shapeless_blob_has_no_plane():
    pts = np.random.default_rng(0).normal(size=(5000, 3))
    with pytest.raises(SceneError, match="no support plane"):
        fit_support_plane(pts)


def test_the_fit_is_deterministic_for_a_seed():
    pts = scan(default_truth(), spacing=0.003, noise=0.001).points
    a, b = fit_support_plane(pts, seed=3), fit_support_plane(pts, seed=3)
    assert np.array_equal(a.normal, b.normal) and a.height_m == b.height_m


def test_plane_frame_is_right_handed_with_z_along_the_normal():
    n = np.array([0.1, -0.2, 0.97])
    n /= np.linalg.norm(n)
    T = plane_frame(n, 0.3)
    R = T[:3, :3]
    assert np.allclose(R.T @ R, np.eye(3)) and np.linalg.det(R) == pytest.approx(1.0)
    assert np.allclose(R[:, 2], n) and T[:3, 3] @ n == pytest.approx(0.3)


def test_plane_round_trip_between_base_and_plane_coordinates():
    truth = default_truth()
    T = make_T(rot_x(0.05), (0, 0, 0.1))
    pts = scan(truth, spacing=0.004).points @ T[:3, :3].T + T[:3, 3]
    plane = fit_support_plane(pts)
    assert np.allclose(plane.to_base(plane.to_plane(pts)), pts)
    # the box top is 0.03 m above the plane whatever the tilt
    top = plane.to_plane(pts)[:, 2]
    assert np.sum(np.abs(top - 0.03) < 0.001) > 100


def test_table_only_and_an_object_plane_the_table_is_the_support():
    truth = type(default_truth())([table(), box("slab", 0, 0, 0.3, 0.25, 0.05)], "table")
    plane = fit_support_plane(scan(truth, spacing=0.002).points)
    assert abs(plane.height_m) < 1e-4  # the table (0.125 m^2 seen) beats the slab (0.075)
