"""Support plane: exact on synthetic tables, level check against the expected up, bad input."""

from __future__ import annotations

import math

import numpy as np
import pytest

from armstereo.scene.errors import SceneError
from armstereo.scene.plane import fit_support_plane, plane_frame, refine_from_cells
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


def _noisy_table_with_low_tops(seed: int) -> np.ndarray:
    """A low-texture table (5 mm depth noise, 0.5 x 0.4 m) with two textured low objects on
    its -x side (tops 15 and 20 mm, 1 mm noise, densely sampled): the realistic desk's tray
    and keypad, where a plane a few degrees off through their tops and the table's far side
    holds about as many points in the 5 mm band as the table."""
    rng = np.random.default_rng(seed)
    tab = np.column_stack([rng.uniform(-0.25, 0.25, 60_000), rng.uniform(-0.2, 0.2, 60_000),
                           rng.normal(0.0, 0.005, 60_000)])
    tops = []
    for (x0, x1, y0, y1, h, n) in ((-0.25, -0.05, 0.0, 0.2, 0.015, 10_000),
                                   (-0.25, -0.13, -0.2, -0.02, 0.02, 4_000)):
        tops.append(np.column_stack([rng.uniform(x0, x1, n), rng.uniform(y0, y1, n),
                                     rng.normal(h, 0.001, n)]))
        inside = (tab[:, 0] > x0) & (tab[:, 0] < x1) & (tab[:, 1] > y0) & (tab[:, 1] < y1)
        tab = tab[~inside]
    return np.vstack([tab, *tops])


def test_a_plane_through_object_tops_loses_to_the_table_beneath_them(monkeypatch):
    pts = _noisy_table_with_low_tops(1)
    plane = fit_support_plane(pts)
    assert plane.tilt_deg < 0.5 and abs(plane.height_m) < 0.004
    # the same cloud ranked by inliers alone picks the tilted plane: the test can fail
    monkeypatch.setattr("armstereo.scene.plane.BELOW_WEIGHT", 0.0)
    assert fit_support_plane(pts).tilt_deg > 1.0



def _heavy_tailed_table_with_a_skirted_tray(seed: int) -> np.ndarray:
    """A low-texture table as the realistic desk's matchers see it: symmetric, heavy-tailed
    depth noise (70 % 3 mm, 30 % 8 mm; MAD sigma ~4 mm), a 15 mm tray on the -x side seen
    densely, and a 2 cm skirt of table points 2-4 mm too high around it (foreground
    fattening, mismatches in its shadow)."""
    rng = np.random.default_rng(seed)
    n = 150_000
    noise = np.where(rng.random(n) < 0.7, rng.normal(0, 0.003, n), rng.normal(0, 0.008, n))
    tab = np.column_stack([rng.uniform(-0.25, 0.25, n), rng.uniform(-0.2, 0.2, n), noise])
    x0, x1, y0, y1 = -0.25, -0.05, -0.05, 0.15
    tab = tab[~((tab[:, 0] > x0) & (tab[:, 0] < x1) & (tab[:, 1] > y0) & (tab[:, 1] < y1))]
    tray = np.column_stack([rng.uniform(x0, x1, 20_000), rng.uniform(y0, y1, 20_000),
                            rng.normal(0.015, 0.002, 20_000)])
    skirt = ((tab[:, 0] > x0 - 0.02) & (tab[:, 0] < x1 + 0.02) & (tab[:, 1] > y0 - 0.02)
             & (tab[:, 1] < y1 + 0.02))
    tab[skirt, 2] += rng.uniform(0.002, 0.004, np.count_nonzero(skirt))
    return np.vstack([tab, tray])


@pytest.mark.parametrize("seed", [1, 2, 4])
def test_the_cell_refit_levels_a_plane_the_point_band_tilts(seed):
    pts = _heavy_tailed_table_with_a_skirted_tray(seed)
    fitted = fit_support_plane(pts)
    refined = refine_from_cells(pts, fitted)
    # measured (seeds 1, 2, 4): point refit 0.12-0.13 deg and +0.19..+0.35 mm, cell refit
    # 0.04-0.06 deg and +0.10..+0.14 mm (the skirt reaches past the 1 cm margin)
    assert fitted.tilt_deg > 0.12  # the point band's tilt: the test can fail
    assert refined.tilt_deg < 0.07
    assert abs(refined.height_m) < 0.00016 and abs(refined.height_m) < abs(fitted.height_m)
    # the reported statistics are those of the new plane's point band
    assert refined.inliers > 0.3 * len(pts) and refined.rms_m < 0.005
    assert refined.area_m2 == pytest.approx(fitted.area_m2, rel=0.05)


def test_the_cell_refit_keeps_an_exact_table_exact():
    cloud = scan(default_truth(), spacing=0.002, noise=0.0005)
    pts = cloud.points + [0, 0, 0.7]
    refined = refine_from_cells(pts, fit_support_plane(pts))
    assert refined.tilt_deg < 0.05 and refined.height_m == pytest.approx(0.7, abs=2e-4)


def test_the_cell_refit_of_too_few_cells_keeps_the_plane():
    # a sparse cloud: 3 cm cells hold ~2 points each, none reaches CELL_MIN_POINTS
    pts = scan(default_truth(), spacing=0.02, noise=0.0005).points
    fitted = fit_support_plane(pts)
    same = refine_from_cells(pts, fitted)
    assert same is fitted
