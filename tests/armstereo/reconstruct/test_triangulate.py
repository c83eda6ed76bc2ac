"""Disparity -> depth -> points, against exact geometry (docs/rectification.md §9, §10.1)."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from armstereo.errors import StereoError
from armstereo.reconstruct.rectify import RectifiedPair, StereoGeometry, rectify_pair
from armstereo.reconstruct.triangulate import (
    depth_from_disparity,
    depth_in_original_view,
    point_cloud,
    points_in_camera,
    points_rect,
)
from armstereo.transforms import invert, make_T, rot_x, rot_y, rot_z, transform_points

K = np.array([[610.0, 0, 322.0], [0, 600.0, 236.0], [0, 0, 1]])
DIST = np.array([-0.12, 0.05, 0.001, -0.0005, 0.0])
SIZE = (640, 480)


def camera_above(offset, yaw_deg: float = 0.0, tilt_deg: float = 0.0,
                 height: float = 0.6) -> np.ndarray:
    """Camera looking down at the plane z = 0 of base (camera x = base x)."""
    R = rot_x(math.pi) @ rot_z(math.radians(yaw_deg)) @ rot_x(math.radians(tilt_deg))
    return make_T(R, np.array([0.0, 0.0, height]) + np.asarray(offset, dtype=float))


def rectified(offset=(0.07, 0.01, 0.0), dist=None, depth_range=None) -> RectifiedPair:
    T1, T2 = camera_above((0, 0, 0), 0.0, 5.0), camera_above(offset, 3.0, -2.0)
    img = np.zeros(SIZE[::-1], np.uint8)
    return rectify_pair(img, img, K, dist, T1, K, dist, T2, depth_range=depth_range)


def plane_disparity(g: StereoGeometry, normal=(0.0, 0.0, 1.0), offset: float = 0.0):
    """Exact disparity (float64) of the base-frame plane n.X = offset seen by the rectified
    left camera, and the depth along the rectified axis."""
    n = np.asarray(normal, dtype=float)
    w, h = g.size
    u, v = np.meshgrid(np.arange(w, dtype=np.float64), np.arange(h, dtype=np.float64))
    rays_rect = np.stack([(u - g.cx_left) / g.fx, (v - g.cy) / g.fy, np.ones_like(u)], axis=-1)
    rays = rays_rect @ g.R_rect  # base-frame directions (R^T applied to each row)
    z = (offset - n @ g.c_left) / (rays @ n)  # rays have unit rectified z, so t is depth
    return g.fx * g.baseline / z + g.disparity_offset, z


def test_constant_disparity_gives_constant_depth():
    g = rectified().geometry
    d = np.full(g.size[::-1], g.disparity_offset + 42.0, dtype=np.float32)
    z = depth_from_disparity(d, g)
    assert z.dtype == np.float32
    assert np.allclose(z, g.fx * g.baseline / 42.0, rtol=1e-6)


def test_unknown_and_infinite_disparities_give_nan():
    g = rectified().geometry
    d = np.full(g.size[::-1], g.disparity_offset + 10.0, dtype=np.float32)
    d[0, 0] = np.nan
    d[0, 1] = g.disparity_offset  # a point at infinity
    d[0, 2] = g.disparity_offset - 3.0  # behind the cameras
    z = depth_from_disparity(d, g)
    assert np.isnan(z[0, :3]).all() and np.isfinite(z[0, 3:]).all()
    pts, cols = point_cloud(d, g, np.zeros(d.shape, np.uint8))
    assert len(pts) == d.size - 3 and np.isfinite(pts).all()


def test_points_reproject_to_their_pixels_exactly():
    rp = rectified()
    g = rp.geometry
    rng = np.random.default_rng(0)
    d = g.disparity_offset + rng.uniform(5, 80, g.size[::-1])  # float64: exact path
    pts = points_rect(d, g)
    assert pts.dtype == np.float64
    X = transform_points(g.T_base_rectleft, pts.reshape(-1, 3))
    h = np.c_[X, np.ones(len(X))]
    m1, m2 = h @ rp.rectification.P1.T, h @ rp.rectification.P2.T
    m1, m2 = m1[:, :2] / m1[:, 2:], m2[:, :2] / m2[:, 2:]
    w, hh = g.size
    u, v = np.meshgrid(np.arange(w), np.arange(hh))
    assert np.allclose(m1[:, 0], u.ravel(), atol=1e-9) and np.allclose(m1[:, 1], v.ravel(),
                                                                      atol=1e-9)
    assert np.allclose(m1[:, 0] - m2[:, 0], d.ravel(), rtol=1e-9)
    assert np.allclose(m2[:, 1], v.ravel(), atol=1e-9)
    # depth relation to 1e-9 relative
    z = depth_from_disparity(d, g)
    assert np.allclose(z, pts[..., 2], rtol=1e-12)
    assert np.allclose(z, g.fx * g.baseline / (d - g.disparity_offset), rtol=1e-9)


def test_Q_handles_non_square_pixels():
    g = StereoGeometry(fx=900.0, fy=870.0, cx_left=330.0, cx_right=300.0, cy=250.0,
                       baseline=0.12, size=(64, 48), R_rect=rot_y(0.2), c_left=np.zeros(3),
                       c_right=rot_y(0.2).T @ [0.12, 0, 0])
    rng = np.random.default_rng(1)
    d = 30.0 + rng.uniform(1, 50, (48, 64))
    pts = points_rect(d, g)
    v, u = np.mgrid[:48, :64]
    hom = np.stack([u, v, d, np.ones_like(d)], axis=-1) @ g.Q.T
    assert np.allclose(hom[..., :3] / hom[..., 3:], pts, rtol=1e-12)
    # and through P: the point projects back with fy, not fx
    assert np.allclose(g.fy * pts[..., 1] / pts[..., 2] + g.cy, v, atol=1e-9)


@pytest.mark.parametrize("offset", [(0.07, 0.01, 0.0), (-0.05, 0.0, 0.01), (0.01, 0.06, 0.0)])
def test_known_plane_triangulates_back(offset):
    rp = rectified(offset)
    g = rp.geometry
    d, _ = plane_disparity(g)
    pts, _ = point_cloud(d.astype(np.float32), g, rp.left, mask=rp.left_mask)
    assert len(pts) > 0.5 * rp.left_mask.size
    assert np.abs(pts[:, 2]).max() < 2e-6  # z = 0 in base, float32 disparity
    tilted = rot_x(0.3) @ [0, 0, 1.0]
    d2, z2 = plane_disparity(g, tilted, -0.05)
    ok = np.isfinite(d2) & (z2 > 0)
    pts2, _ = point_cloud(np.where(ok, d2, np.nan), g, rp.left, mask=rp.left_mask)
    assert np.abs(pts2 @ tilted + 0.05).max() < 1e-6  # float32 output


def test_colors_come_from_the_rectified_left_image():
    g = rectified().geometry
    w, h = g.size
    d = np.full((h, w), np.nan, np.float32)
    d[10, 20] = g.disparity_offset + 30.0
    d[11, 21] = g.disparity_offset + 31.0
    img = np.zeros((h, w, 3), np.uint8)
    img[10, 20] = (1, 2, 3)
    img[11, 21] = (4, 5, 6)
    pts, cols = point_cloud(d, g, img, frame="rect")
    assert cols.tolist() == [[1, 2, 3], [4, 5, 6]]
    assert pts[0, 2] == pytest.approx(g.fx * g.baseline / 30.0, rel=1e-6)
    _, grey = point_cloud(d, g, img[..., 2].copy())
    assert grey.tolist() == [[3, 3, 3], [6, 6, 6]]
    mask = np.zeros((h, w), bool)
    mask[11, 21] = True
    assert len(point_cloud(d, g, img, mask=mask)[0]) == 1


def test_base_and_camera_frames_agree():
    rp = rectified()
    g = rp.geometry
    d, _ = plane_disparity(g)
    pts_base, _ = point_cloud(d, g, rp.left)
    pts_rect, _ = point_cloud(d, g, rp.left, frame="rect")
    back = points_in_camera(pts_base.astype(np.float64), g.T_base_rectleft)
    assert np.allclose(back, pts_rect, atol=1e-5)
    cam = points_in_camera(pts_base.astype(np.float64), rp.T_base_left_camera)
    assert np.allclose(cam, transform_points(invert(rp.T_base_left_camera), pts_base), atol=1e-9)


def ground_truth_depth(T_base_cam: np.ndarray, dist, normal, offset) -> np.ndarray:
    """z-depth of the plane n.X = offset in the ORIGINAL camera, per pixel."""
    u, v = np.meshgrid(np.arange(SIZE[0], dtype=np.float64),
                       np.arange(SIZE[1], dtype=np.float64))
    pix = np.stack([u.ravel(), v.ravel()], axis=1)
    if dist is None:
        xy = np.linalg.solve(K, np.c_[pix, np.ones(len(pix))].T).T[:, :2]
    else:
        crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 50, 1e-12)
        xy = cv2.undistortPointsIter(pix[:, None, :], K, dist, np.eye(3), np.eye(3),
                                     crit).reshape(-1, 2)
    rays = np.c_[xy, np.ones(len(xy))] @ T_base_cam[:3, :3].T  # camera z component is 1
    n = np.asarray(normal, dtype=float)
    z = (offset - n @ T_base_cam[:3, 3]) / (rays @ n)
    return z.reshape(SIZE[1], SIZE[0])


@pytest.mark.parametrize("dist", [None, DIST])
@pytest.mark.parametrize("offset", [(0.07, 0.01, 0.0), (-0.06, 0.0, 0.0), (0.01, 0.06, 0.0)])
def test_depth_in_original_view_matches_ground_truth(dist, offset):
    rp = rectified(offset, dist)
    g = rp.geometry
    normal, plane = rot_x(0.25) @ rot_y(-0.2) @ [0, 0, 1.0], -0.02
    d, _ = plane_disparity(g, normal, plane)
    est = depth_in_original_view(d.astype(np.float32), rp)
    truth = ground_truth_depth(rp.T_base_left_camera, dist, normal, plane)
    assert est.shape == truth.shape and est.dtype == np.float32
    ok = np.isfinite(est)
    assert ok.mean() > 0.97  # only a thin band at the borders is lost
    assert np.abs(est[ok] / truth[ok] - 1).max() < 2e-4


def test_bad_input_is_refused():
    g = rectified().geometry
    with pytest.raises(StereoError, match="canvas"):
        depth_from_disparity(np.zeros((10, 10), np.float32), g)
    with pytest.raises(StereoError, match="2D float"):
        depth_from_disparity(np.zeros(g.size[::-1], np.uint8), g)
    d = np.zeros(g.size[::-1], np.float32)
    with pytest.raises(StereoError, match="frame"):
        point_cloud(d, g, np.zeros(d.shape, np.uint8), frame="world")
    with pytest.raises(StereoError, match="colour image"):
        point_cloud(d, g, np.zeros((5, 5), np.uint8))


# ----------------------------------------------------------------------------------------------
# Contracts the mutation run (bench/results/mutation.md) found untested
# ----------------------------------------------------------------------------------------------
def small_geometry(w: int = 7, h: int = 4) -> StereoGeometry:
    return StereoGeometry(fx=600.0, fy=600.0, cx_left=3.0, cx_right=1.0, cy=2.0, baseline=0.1,
                          size=(w, h), R_rect=np.eye(3), c_left=np.zeros(3),
                          c_right=np.array([0.1, 0.0, 0.0]))


@pytest.mark.parametrize("dtype", [np.float16, np.float32, np.float64, np.longdouble])
def test_outputs_are_float32_unless_the_disparity_is_float64(dtype):
    g = small_geometry()
    d = np.full(g.size[::-1], 32.0, dtype=dtype)
    want = np.float64 if np.dtype(dtype) == np.float64 else np.float32
    assert depth_from_disparity(d, g).dtype == want
    assert points_rect(d, g).dtype == want


def test_size_mismatches_are_reported_as_width_x_height():
    g = small_geometry(7, 4)
    with pytest.raises(StereoError, match=r"disparity is 5x3 but the rectified canvas is 7x4"):
        depth_from_disparity(np.zeros((3, 5), np.float32), g)
    d = np.zeros((4, 7), np.float32)
    with pytest.raises(StereoError, match=r"colour image is 6x2 but the disparity is 7x4"):
        point_cloud(d, g, np.zeros((2, 6), np.uint8))


def test_holes_do_not_bias_the_depth_of_their_neighbours():
    """A constant disparity with scattered holes: every original-view pixel that still gets a
    depth gets the hole-free one, however little of its sampling footprint fell on a hole."""
    rp = rectified()
    g = rp.geometry
    d = np.full(g.size[::-1], g.disparity_offset + 42.0, np.float32)
    full = depth_in_original_view(d, rp)
    holes = np.random.default_rng(4).random(d.shape) < 0.05
    est = depth_in_original_view(np.where(holes, np.nan, d), rp)
    ok = np.isfinite(est)
    assert 0.5 < ok.mean() < np.isfinite(full).mean()
    np.testing.assert_allclose(est[ok], full[ok], rtol=1e-6)
