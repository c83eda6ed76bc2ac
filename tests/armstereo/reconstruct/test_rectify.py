"""Fusiello rectification against the oracles of docs/rectification.md §10.1."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from armstereo.camera_model import Intrinsics
from armstereo.errors import StereoError
from armstereo.reconstruct.rectify import (
    RectificationPlan,
    factor_projection,
    fusiello,
    rectified_geometry,
    rectify_pair,
    rq,
    second_view_is_left,
    warped_bounds,
)
from armstereo.transforms import make_T, rot_x, rot_y, rot_z
from tests.support.geometry import random_rotation

SIZE = (640, 480)
ROW_TOL = 1e-9  # px; float64 gives ~1e-12 (the issue asks for 1e-6)
EX = np.array([[0.0, 0, 0], [0, 0, -1], [0, 1, 0]])  # [e_x]x: F of a rectified pair

# Baseline directions in camera 1's frame: horizontal, vertical, diagonal, both signs, and some
# with a forward component.
DIRECTIONS = [(1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, -1, 0), (1, 1, 0), (-1, 1, 0), (1, -1, 0.3),
              (-0.7, -0.7, -0.4), (0.3, 1, 0.5), (1, 0.2, -0.6)]


def random_K(rng: np.random.Generator, skew: bool = True) -> np.ndarray:
    fx = rng.uniform(400, 1000)
    return np.array([[fx, rng.uniform(-5, 5) if skew else 0.0, rng.uniform(280, 360)],
                     [0, fx * rng.uniform(0.9, 1.1), rng.uniform(200, 280)], [0, 0, 1]])


def random_rig(seed: int, direction, skew: bool = True):
    """Two cameras (K, T_base_cam) about 2 m above z = 0 looking down, baseline along
    ``direction`` in camera 1's frame; rotations up to 20 deg."""
    rng = np.random.default_rng(seed)
    R_down = rot_x(math.pi)  # camera z axis along base -z
    R1 = R_down @ random_rotation(rng, 20)
    c1 = np.array([0.1, -0.2, 2.0]) + rng.normal(scale=0.05, size=3)
    d = np.asarray(direction, dtype=float)
    c2 = c1 + R1 @ (d / np.linalg.norm(d)) * rng.uniform(0.1, 0.3)
    R2 = R1 @ random_rotation(rng, 20)
    return (random_K(rng, skew), make_T(R1, c1)), (random_K(rng, skew), make_T(R2, c2))


def ppm(K: np.ndarray, T_base_cam: np.ndarray) -> np.ndarray:
    R, c = T_base_cam[:3, :3], T_base_cam[:3, 3]
    return K @ np.hstack([R.T, (-R.T @ c)[:, None]])


def project(P: np.ndarray, X: np.ndarray) -> np.ndarray:
    h = np.c_[X, np.ones(len(X))] @ P.T
    return h[:, :2] / h[:, 2:]


def apply_h(H: np.ndarray, m: np.ndarray) -> np.ndarray:
    h = np.c_[m, np.ones(len(m))] @ H.T
    return h[:, :2] / h[:, 2:]


def points_in_front(cam1, cam2, n: int = 200, seed: int = 0) -> np.ndarray:
    """Points 1-4 m in front of camera 1 that are also in front of camera 2."""
    rng = np.random.default_rng(seed)
    K, T = cam1
    pix = np.c_[rng.uniform(0, SIZE[0], n), rng.uniform(0, SIZE[1], n), np.ones(n)]
    X = T[:3, :3] @ (np.linalg.solve(K, pix.T) * rng.uniform(1, 4, n)) + T[:3, 3:4]
    X = X.T
    z2 = (X - cam2[1][:3, 3]) @ cam2[1][:3, 2]
    return X[z2 > 0.1]


def rig_cases():
    return [(seed, d) for seed, d in enumerate(DIRECTIONS)] + [(100 + s, DIRECTIONS[s % 3])
                                                               for s in range(5)]


# ----------------------------------------------------------------------------------------------
def test_rq_positive_diagonal():
    rng = np.random.default_rng(1)
    for _ in range(20):
        M = rng.normal(size=(3, 3))
        U, Q = rq(M)
        assert np.allclose(U @ Q, M, atol=1e-12)
        assert np.allclose(np.tril(U, -1), 0) and np.all(np.diag(U) > 0)
        assert np.allclose(Q @ Q.T, np.eye(3), atol=1e-12)


@pytest.mark.parametrize("scale", [1.0, -1.0, 2.5, -0.003, 1e4])
def test_factor_projection_recovers_K_R_c_at_any_scale(scale):
    (K, T), _ = random_rig(3, (1, 0, 0))
    A, R, c = factor_projection(scale * ppm(K, T))
    assert np.allclose(A, K, rtol=1e-12, atol=1e-9)
    assert np.allclose(R, T[:3, :3].T, atol=1e-12)
    assert np.allclose(c, T[:3, 3], atol=1e-12)


@pytest.mark.parametrize("seed,direction", rig_cases())
@pytest.mark.parametrize("centred", [False, True])
def test_random_rigs_rows_agree_and_points_project(seed, direction, centred):
    cam1, cam2 = random_rig(seed, direction)
    P1, P2 = ppm(*cam1), ppm(*cam2)
    r = fusiello(P1, P2, image_size=SIZE if centred else None)
    X = points_in_front(cam1, cam2, seed=seed)
    m1, m2 = apply_h(r.H1, project(P1, X)), apply_h(r.H2, project(P2, X))
    assert np.abs(m1[:, 1] - m2[:, 1]).max() < ROW_TOL
    # T-mapped points equal the rectified projections
    assert np.abs(m1 - project(r.P1, X)).max() < 1e-8
    assert np.abs(m2 - project(r.P2, X)).max() < 1e-8
    # centres unchanged
    assert np.allclose(factor_projection(r.P1)[2], cam1[1][:3, 3], atol=1e-9)
    assert np.allclose(factor_projection(r.P2)[2], cam2[1][:3, 3], atol=1e-9)
    # disparity sign (camera 1 is the reference/left camera) and depth from disparity
    A1, Rn, c1 = factor_projection(r.P1)
    A2, _, c2 = factor_projection(r.P2)
    offset = A1[0, 2] - A2[0, 2]
    d = m1[:, 0] - m2[:, 0]
    assert np.all(d - offset > 0)
    Z = (X - c1) @ Rn[2]
    b = np.linalg.norm(c2 - c1)
    assert np.allclose(A1[0, 0] * b / (d - offset), Z, rtol=1e-9, atol=0)


@pytest.mark.parametrize("seed,direction", rig_cases())
def test_shared_orientation_intrinsics_and_axes(seed, direction):
    cam1, cam2 = random_rig(seed, direction)
    r = fusiello(ppm(*cam1), ppm(*cam2), image_size=SIZE)
    A1, R1, c1 = factor_projection(r.P1)
    A2, R2, c2 = factor_projection(r.P2)
    assert np.allclose(R1, R2, atol=1e-12) and np.isclose(np.linalg.det(R1), 1.0)
    assert np.allclose(R1 @ R1.T, np.eye(3), atol=1e-12)
    assert A1[0, 1] == pytest.approx(0, abs=1e-9) and A2[0, 1] == pytest.approx(0, abs=1e-9)
    assert A1[1, 1] == pytest.approx(A2[1, 1], rel=1e-12)
    assert A1[1, 2] == pytest.approx(A2[1, 2], rel=1e-12)
    assert A1[0, 0] == pytest.approx(A1[1, 1], rel=1e-12)  # square pixels: the standard Q holds
    assert np.dot(R1[0], c2 - c1) > 0 and np.allclose(np.cross(R1[0], c2 - c1), 0, atol=1e-12)
    k = cam1[1][:3, 2]  # camera 1's old viewing direction
    assert abs(np.dot(R1[1], k)) < 1e-12


def fundamental(P1: np.ndarray, P2: np.ndarray) -> np.ndarray:
    C1 = np.append(factor_projection(P1)[2], 1.0)
    e2 = P2 @ C1
    ex = np.array([[0, -e2[2], e2[1]], [e2[2], 0, -e2[0]], [-e2[1], e2[0], 0]])
    return ex @ P2 @ np.linalg.pinv(P1)


@pytest.mark.parametrize("seed,direction", rig_cases()[:6])
def test_epipoles_at_infinity(seed, direction):
    cam1, cam2 = random_rig(seed, direction)
    r = fusiello(ppm(*cam1), ppm(*cam2), image_size=SIZE)
    F = fundamental(r.P1, r.P2)
    F = F / np.linalg.norm(F) * np.sign(F[2, 1])
    assert np.allclose(F, EX / np.linalg.norm(EX), atol=1e-9)


@pytest.mark.parametrize("s1,s2", [(-1.0, 1.0), (1.0, -1.0), (-1.0, -1.0), (3.0, 0.02),
                                   (-250.0, 7.0)])
def test_invariant_to_scaling_the_ppms(s1, s2):
    cam1, cam2 = random_rig(5, (1, 0.3, 0.1))
    P1, P2 = ppm(*cam1), ppm(*cam2)
    ref = fusiello(P1, P2, image_size=SIZE)
    got = fusiello(s1 * P1, s2 * P2, image_size=SIZE)
    for a, b in zip(ref, got, strict=True):
        assert np.allclose(a, b, rtol=1e-10, atol=1e-9)


def test_identity_case_keeps_everything():
    K = np.array([[600.0, 0, 319.5], [0, 600.0, 239.5], [0, 0, 1]])
    T1, T2 = np.eye(4), make_T(np.eye(3), [0.1, 0, 0])
    r = fusiello(ppm(K, T1), ppm(K, T2), image_size=SIZE)
    assert np.allclose(r.H1, np.eye(3), atol=1e-12) and np.allclose(r.H2, np.eye(3), atol=1e-12)
    assert np.allclose(factor_projection(r.P1)[1], np.eye(3), atol=1e-12)
    img = np.random.default_rng(0).integers(0, 256, (480, 640, 3), dtype=np.uint8)
    rp = rectify_pair(img, img[:, ::-1].copy(), K, None, T1, K, None, T2)
    assert rp.size == SIZE and not rp.swapped
    assert np.array_equal(rp.left, img) and rp.left_mask.all()
    assert np.allclose(rp.Q, [[1, 0, 0, -319.5], [0, 1, 0, -239.5], [0, 0, 0, 600],
                              [0, 0, 10, 0]])


@pytest.mark.parametrize("tilt_deg", [0.0, 3.0])
def test_forward_baseline_is_refused(tilt_deg):
    K = np.array([[600.0, 0, 319.5], [0, 600.0, 239.5], [0, 0, 1]])
    forward = rot_y(math.radians(tilt_deg)) @ np.array([0, 0, 0.1])
    with pytest.raises(StereoError, match=r"optical axis \(angle [0-9.]+ deg\)"):
        fusiello(ppm(K, np.eye(4)), ppm(K, make_T(np.eye(3), forward)))


def test_zero_baseline_and_bad_input_are_refused():
    K = np.array([[600.0, 0, 319.5], [0, 600.0, 239.5], [0, 0, 1]])
    P = ppm(K, np.eye(4))
    with pytest.raises(StereoError, match="same place"):
        fusiello(P, 2 * P)
    with pytest.raises(StereoError, match="3x4"):
        fusiello(P[:, :3], P)
    with pytest.raises(StereoError, match="singular"):
        fusiello(np.zeros((3, 4)), P)
    img = np.zeros((480, 640), np.uint8)
    T2 = make_T(np.eye(3), [0.1, 0, 0])
    with pytest.raises(StereoError, match="non-empty uint8"):
        rectify_pair(np.zeros((0, 0), np.uint8), img, K, None, np.eye(4), K, None, T2)
    with pytest.raises(StereoError, match="rigid"):
        rectify_pair(img, img, K, None, 2 * np.eye(4), K, None, T2)


# Example PPMs circulating with reproductions of rectify.m (docs/rectification.md §10.2).
PO1 = np.array([[976.5, 53.82, -239.8, 387500], [98.49, 933.3, 157.4, 242800],
                [.579, .1108, .8077, 1118]])
PO2 = np.array([[976.7, 53.76, -240, 40030], [98.68, 931.0, 156.71, 251700],
                [.5766, .1141, .8089, 1174]])


def test_regression_numbers_of_the_example_ppms():
    # Paper settings (averaged A, fy kept, no centering): docs/rectification.md §10.2.
    r = fusiello(PO1, PO2, square_pixels=False)
    A, Rn, c1 = factor_projection(r.P1)
    c2 = factor_projection(r.P2)[2]
    assert np.allclose(c1, [-623.653, -37.156, -932.014], atol=1e-3)
    assert np.allclose(c2, [-335.949, -31.505, -1207.439], atol=1e-3)
    assert np.linalg.norm(c2 - c1) == pytest.approx(398.327, abs=1e-3)
    assert np.allclose(A, [[934.136, 0, 376.473], [0, 905.556, 288.771], [0, 0, 1]], atol=1e-3)
    assert np.allclose(Rn[0], [0.72228, 0.01419, -0.69145], atol=1e-5)
    assert np.allclose(apply_h(r.H1, np.array([[384.0, 288.0]])), [[252.0, 289.1]], atol=0.05)
    # Default (square pixels): same rotation and centres, fx = fy = mean of the averaged A's.
    s = fusiello(PO1, PO2)
    As, Rs, _ = factor_projection(s.P1)
    assert np.allclose(Rs, Rn, atol=1e-12)
    assert As[0, 0] == pytest.approx(As[1, 1], rel=1e-12)
    assert As[0, 0] == pytest.approx((934.136 + 905.556) / 2, abs=1e-3)


def test_centering_puts_both_centres_on_one_column_and_canvas_at_origin():
    size = (768, 576)
    r = fusiello(PO1, PO2, image_size=size)
    centre = np.array([[(size[0] - 1) / 2, (size[1] - 1) / 2]])
    c1, c2 = apply_h(r.H1, centre)[0], apply_h(r.H2, centre)[0]
    assert c1[0] == pytest.approx(c2[0], abs=1e-9)  # each centre shifted onto the same column
    b1, b2 = warped_bounds(r.H1, size), warped_bounds(r.H2, size)
    assert min(b1[0], b2[0]) == pytest.approx(0, abs=1e-9)
    assert min(b1[1], b2[1]) == pytest.approx(0, abs=1e-9)
    # the un-centred warp pushed the centre 132 px left; centering keeps it in the canvas middle
    assert c1[0] == pytest.approx((max(b1[2], b2[2])) / 2, rel=0.1)


# ----------------------------------------------------------------------------------------------
# Image level
# ----------------------------------------------------------------------------------------------
MARKERS = np.array([[x, y, 0.0] for x in np.linspace(-0.25, 0.25, 4)
                    for y in np.linspace(-0.18, 0.18, 3)])
MARKER_SIGMA = 0.012  # m


def render_plane(K: np.ndarray, dist: np.ndarray | None, T_base_cam: np.ndarray,
                 size=SIZE) -> np.ndarray:
    """Ray-cast the plane z = 0 of base: dark background, bright Gaussian markers."""
    w, h = size
    u, v = np.meshgrid(np.arange(w, dtype=np.float64), np.arange(h, dtype=np.float64))
    pix = np.stack([u.ravel(), v.ravel()], axis=1)
    if dist is not None:
        crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 50, 1e-12)
        xy = cv2.undistortPointsIter(pix[:, None, :], K, dist, np.eye(3), np.eye(3),
                                     crit).reshape(-1, 2)
        rays = np.c_[xy, np.ones(len(xy))]
    else:
        rays = np.linalg.solve(K, np.c_[pix, np.ones(len(pix))].T).T
    rays = rays @ T_base_cam[:3, :3].T
    t = -T_base_cam[2, 3] / rays[:, 2]
    X = T_base_cam[:3, 3] + rays * t[:, None]
    img = np.full(len(X), 30.0)  # flat: a textured background would bias the centroids
    for m in MARKERS:
        img += 200.0 * np.exp(-((X[:, 0] - m[0]) ** 2 + (X[:, 1] - m[1]) ** 2)
                              / (2 * MARKER_SIGMA ** 2))
    return np.clip(img, 0, 255).reshape(h, w).astype(np.uint8)


def marker_centroids(img: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """Intensity-weighted centroids of bright blobs wholly inside the valid area."""
    n, labels, stats, _ = cv2.connectedComponentsWithStats((img > 100).astype(np.uint8))
    out = []
    valid = cv2.erode(mask.astype(np.uint8), np.ones((5, 5), np.uint8)).astype(bool)
    for k in range(1, n):
        x, y, w, h, area = stats[k]
        blob = labels == k
        if area < 30 or not valid[blob].all():
            continue
        wgt = np.where(blob, img.astype(np.float64) - 100, 0)
        ys, xs = np.mgrid[: img.shape[0], : img.shape[1]]
        out.append([(wgt * xs).sum() / wgt.sum(), (wgt * ys).sum() / wgt.sum()])
    return np.array(out)


def camera_above(offset, yaw_deg: float = 0.0, tilt_deg: float = 0.0) -> np.ndarray:
    R = rot_x(math.pi) @ rot_z(math.radians(yaw_deg)) @ rot_x(math.radians(tilt_deg))
    return make_T(R, np.array([0.0, 0.0, 0.6]) + np.asarray(offset, dtype=float))


@pytest.mark.parametrize("offset,expect_rotation", [
    ((0.06, 0.0, 0.0), 0.0),      # camera moves along its +x (base x): stays upright
    ((-0.06, 0.0, 0.0), 0.0),     # moves to its left: views swap, still upright
    ((0.002, 0.06, 0.0), 90.0),   # (nearly) vertical in the image: rotated by 90 deg
    ((0.04, -0.04, 0.01), -45.0),  # diagonal
])
def test_markers_land_on_the_same_row(offset, expect_rotation):
    K = np.array([[610.0, 0, 322.0], [0, 600.0, 236.0], [0, 0, 1]])
    dist = np.array([-0.12, 0.05, 0.001, -0.0005, 0.0])
    T1, T2 = camera_above((0, 0, 0)), camera_above(offset, yaw_deg=4.0, tilt_deg=-3.0)
    rp = rectify_pair(render_plane(K, dist, T1), render_plane(K, dist, T2), K, dist, T1,
                      K, dist, T2)
    assert rp.swapped == (offset[0] < 0)  # camera x is base x in camera_above()
    assert abs(((rp.rotation_deg - expect_rotation) + 180) % 360 - 180) < 8
    ml, mr = marker_centroids(rp.left, rp.left_mask), marker_centroids(rp.right, rp.right_mask)
    # the rectified PPMs say where each 3D marker must appear; pair detections through them
    el, er = project(rp.rectification.P1, MARKERS), project(rp.rectification.P2, MARKERS)
    found = 0
    for a, b in zip(el, er, strict=True):
        dl, dr = np.linalg.norm(ml - a, axis=1), np.linalg.norm(mr - b, axis=1)
        if dl.min() > 1.0 or dr.min() > 1.0:
            continue  # not wholly visible in both rectified views
        left, right = ml[dl.argmin()], mr[dr.argmin()]
        assert abs(left[1] - right[1]) < 0.1  # same row
        assert dl.min() < 0.2 and dr.min() < 0.2  # where the geometry says
        assert left[0] - right[0] > rp.geometry.disparity_offset  # positive depth
        found += 1
    assert found >= 6


def test_remap_maps_equal_the_homographies_without_distortion():
    K1 = np.array([[600.0, 2.0, 320.0], [0, 580.0, 240.0], [0, 0, 1]])  # skew in the input
    K2 = np.array([[630.0, 0, 310.0], [0, 640.0, 250.0], [0, 0, 1]])
    T1, T2 = camera_above((0, 0, 0)), camera_above((0.05, 0.02, 0.01), 6.0, 4.0)
    img1, img2 = render_plane(K1, None, T1), render_plane(K2, None, T2)
    rp = rectify_pair(img1, img2, K1, None, T1, K2, None, T2)
    w, h = rp.size
    u, v = np.meshgrid(np.arange(w, dtype=np.float64), np.arange(h, dtype=np.float64))
    for H, (mx, my) in ((rp.rectification.H1, rp.maps_left), (rp.rectification.H2,
                                                               rp.maps_right)):
        src = apply_h(np.linalg.inv(H), np.stack([u.ravel(), v.ravel()], axis=1))
        assert np.abs(src[:, 0] - mx.ravel()).max() < 2e-3
        assert np.abs(src[:, 1] - my.ravel()).max() < 2e-3
    warped = cv2.warpPerspective(img1, rp.rectification.H1, rp.size, flags=cv2.INTER_LINEAR)
    inner = cv2.erode(rp.left_mask.astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool)
    diff = np.abs(warped.astype(int) - rp.left.astype(int))[inner]
    assert diff.max() <= 2 and diff.mean() < 0.3


def test_rectified_geometry_matches_rectify_pair_and_fusiello():
    cam1, cam2 = random_rig(7, (1, 0.2, 0), skew=False)
    intr1, intr2 = Intrinsics(*SIZE, cam1[0]), Intrinsics(*SIZE, cam2[0])
    geom, swapped = rectified_geometry(intr1, cam1[1], intr2, cam2[1])
    r = fusiello(ppm(*cam1), ppm(*cam2), image_size=SIZE)
    A1 = factor_projection(r.P1)[0]
    assert not swapped
    assert geom.fx == pytest.approx(A1[0, 0]) and geom.cx_left == pytest.approx(A1[0, 2])
    img = np.zeros((480, 640), np.uint8)
    rp = rectify_pair(img, img, cam1[0], None, cam1[1], cam2[0], None, cam2[1])
    assert rp.size == geom.size and np.allclose(rp.rectification.H1, r.H1)


def same_fields(a, b) -> bool:
    """Dataclasses with array fields, field by field, exactly."""
    return all(np.array_equal(getattr(a, f), getattr(b, f)) for f in a.__dataclass_fields__)


def test_one_plan_gives_the_geometry_and_the_images_rectify_pair_gives():
    cam1, cam2 = random_rig(9, (-1, 0.1, 0), skew=False)
    intr1, intr2 = Intrinsics(*SIZE, cam1[0]), Intrinsics(*SIZE, cam2[0])
    plan = RectificationPlan.from_views(intr1, cam1[1], intr2, cam2[1])
    img1 = np.random.default_rng(1).integers(0, 256, (480, 640), dtype=np.uint8)
    img2 = np.ascontiguousarray(img1[:, ::-1])
    for depth_range in (None, (0.8, 3.0)):
        geom, swapped = rectified_geometry(intr1, cam1[1], intr2, cam2[1],
                                           depth_range=depth_range)
        assert same_fields(plan.geometry(depth_range=depth_range), geom)
        assert plan.swapped == swapped
        rp = rectify_pair(img1, img2, cam1[0], None, cam1[1], cam2[0], None, cam2[1],
                          depth_range=depth_range)
        again = plan.rectify(img1, img2, depth_range=depth_range)
        assert again.swapped and np.array_equal(again.left, rp.left)
        assert np.array_equal(again.right_mask, rp.right_mask)
        assert same_fields(again.geometry, rp.geometry)
    with pytest.raises(StereoError, match="image is 320x480, its calibration 640x480"):
        plan.rectify(img1[:, :320], img2)


def test_depth_range_aligns_far_with_disparity_zero():
    cam1, cam2 = random_rig(11, (1, 0, 0), skew=False)
    intr1, intr2 = Intrinsics(*SIZE, cam1[0]), Intrinsics(*SIZE, cam2[0])
    geom, _ = rectified_geometry(intr1, cam1[1], intr2, cam2[1], depth_range=(1.0, 3.0))
    d_far, d_near = geom.disparity_window(1.0, 3.0)
    assert d_far == pytest.approx(0, abs=1e-9)
    assert d_near == pytest.approx(geom.fx * geom.baseline * (1 - 1 / 3))


def test_left_is_chosen_so_rotation_stays_within_90_degrees():
    for angle in np.arange(-175.0, 180.0, 15.0):
        a = math.radians(angle)
        T2 = make_T(np.eye(3), [math.cos(a), math.sin(a), 0.0])
        assert second_view_is_left(np.eye(4), T2) == (not -90 < angle <= 90)
        cam2 = (np.diag([600.0, 600.0, 1.0]), T2)
        cam2[0][:2, 2] = (319.5, 239.5)
        intr = Intrinsics(*SIZE, cam2[0])
        geom, swapped = rectified_geometry(intr, np.eye(4), intr, T2)
        R = geom.R_rect  # base = camera 1 frame here; R rotates it into the rectified frame
        left_R = T2[:3, :3].T if swapped else np.eye(3)
        rot = math.degrees(math.atan2((R @ left_R.T)[1, 0], (R @ left_R.T)[0, 0]))
        assert abs(rot) < 90 + 1e-9


def test_oblique_baseline_is_refused_or_capped(caplog):
    K = np.array([[600.0, 0, 319.5], [0, 600.0, 239.5], [0, 0, 1]])
    intr = Intrinsics(*SIZE, K)

    def baseline_at(angle_deg: float) -> np.ndarray:
        a = math.radians(angle_deg)
        return make_T(np.eye(3), [0.1 * math.sin(a), 0.0, 0.1 * math.cos(a)])

    # 20 deg from the optical axis: the rectified cameras turn by 70 deg and the image corners
    # (33 deg off axis) end up behind them
    with pytest.raises(StereoError, match="behind the rectified camera"):
        rectified_geometry(intr, np.eye(4), intr, baseline_at(20))
    geom, _ = rectified_geometry(intr, np.eye(4), intr, baseline_at(50))
    assert max(geom.size) == int(1.5 * 640) and "capped" in caplog.text
    geom, _ = rectified_geometry(intr, np.eye(4), intr, baseline_at(50), out_size=(500, 400))
    assert geom.size == (500, 400)


# ----------------------------------------------------------------------------------------------
# Contracts the mutation run (bench/results/mutation.md) found untested
# ----------------------------------------------------------------------------------------------
K_SMALL = np.array([[60.0, 0, 31.5], [0, 60.0, 23.5], [0, 0, 1]])  # 64x48 images: fast remaps
SMALL = (64, 48)


def sideways(angle_deg: float, length: float = 0.1) -> np.ndarray:
    """Camera 2 translated (same orientation) at ``angle_deg`` from camera 1's optical axis."""
    a = math.radians(angle_deg)
    return make_T(np.eye(3), [length * math.sin(a), 0.0, length * math.cos(a)])


def test_baselines_within_5_degrees_of_the_optical_axis_are_refused():
    # docs/rectification.md: the documented limit is 5 degrees (MIN_BASELINE_ANGLE_DEG)
    K = np.array([[600.0, 0, 319.5], [0, 600.0, 239.5], [0, 0, 1]])
    with pytest.raises(StereoError, match=r"optical axis \(angle 4\.5 deg\)"):
        fusiello(ppm(K, np.eye(4)), ppm(K, sideways(4.5)))
    r = fusiello(ppm(K, np.eye(4)), ppm(K, sideways(5.5)))
    assert np.allclose(factor_projection(r.P2)[2], sideways(5.5)[:3, 3], atol=1e-12)


@pytest.mark.parametrize("scale", [1e-6, 1e-3, 1.0, 1e3, 1e6])
def test_singular_ppm_detection_does_not_depend_on_the_ppms_scale(scale):
    """A PPM whose left 3x3 block has collapsed (optical-axis row within 1e-14 of the x row) is
    refused and one with a small but real third dimension (1e-6) accepted, at any scale."""
    K = np.array([[600.0, 0, 319.5], [0, 600.0, 239.5], [0, 0, 1]])

    def camera(eps: float) -> np.ndarray:
        R = np.array([[1.0, 0, 0], [0, 1.0, 0], [1.0, 0, eps]])  # third row ~ first row
        return K @ np.hstack([R, [[0.1], [0.2], [2.0]]])

    with pytest.raises(StereoError, match="singular"):
        factor_projection(scale * camera(1e-14))
    A, _, _ = factor_projection(scale * camera(1e-6))
    assert np.allclose(A, factor_projection(camera(1e-6))[0], rtol=1e-9)


def test_the_same_place_tolerance_is_inclusive():
    # Two views count as taken from the same place up to 1e-12 of their distance from the
    # origin (at least 1e-12 m), that bound included: P = [I | -c] gives c exactly.
    def at(x: float) -> np.ndarray:
        return np.hstack([np.eye(3), [[-x], [0.0], [0.0]]])

    with pytest.raises(StereoError, match="same place"):
        fusiello(at(0.0), at(1e-12))
    fusiello(at(0.0), at(1e-11))  # ten times the tolerance: a (tiny) real baseline


def test_warped_bounds_are_x_then_y():
    H = np.array([[2.0, 0, 10.0], [0, 0.5, -20.0], [0, 0, 1]])  # x: scale 2, y: scale 0.5
    assert warped_bounds(H, (11, 41)) == (10.0, -20.0, 30.0, 0.0)


def corner_bounds(H: np.ndarray, size) -> np.ndarray:
    w, h = size[0] - 1.0, size[1] - 1.0
    m = apply_h(H, np.array([[0.0, 0], [w, 0], [w, h], [0, h]]))
    return np.r_[m.min(axis=0), m.max(axis=0)]


@pytest.mark.parametrize("seed,direction", [(1, (1, 0, 0)), (5, (1, 0.4, 0.2)),
                                            (2, (-1, 0.3, 0)), (3, (0.2, 1, 0))])  # not capped
@pytest.mark.parametrize("depth_range", [None, (1.0, 3.0)])
def test_canvas_is_the_documented_box_of_the_warped_images(seed, direction, depth_range):
    """Without a depth range: the smallest box holding both warped images. With one: the rows
    both images cover, and the columns from the leftmost content of either image to the left
    image's right edge. Pixel-centre coordinates, so the box starts at (0, 0)."""
    (K1, T1), (K2, T2) = random_rig(seed, direction, skew=False)
    img = np.zeros(SIZE[::-1], np.uint8)
    rp = rectify_pair(img, img, K1, None, T1, K2, None, T2, depth_range=depth_range)
    b1 = corner_bounds(rp.rectification.H1, SIZE)
    b2 = corner_bounds(rp.rectification.H2, SIZE)
    if depth_range is None:
        lo, hi = np.minimum(b1[:2], b2[:2]), np.maximum(b1[2:], b2[2:])
    else:
        lo = np.array([min(b1[0], b2[0]), max(b1[1], b2[1])])
        hi = np.array([b1[2], min(b1[3], b2[3])])
    assert np.allclose(lo, 0.0, atol=1e-6)
    assert rp.size == (int(math.floor(hi[0] + 1e-9)) + 1, int(math.floor(hi[1] + 1e-9)) + 1)
    # the rig's x and y extents differ, so bounds that mixed up x and y would not fit
    assert b1[2] - b1[0] != pytest.approx(b1[3] - b1[1], abs=1.0)


def test_views_sharing_one_row_rectify_and_views_sharing_none_are_refused():
    # Same orientation, baseline along x: the rectified rows of view 2 are its original rows
    # moved by its principal point. cy 47 vs 0 on 48-row images overlap in exactly one row
    # (exact in floating point: rows do not depend on the baseline, and the numbers they do
    # depend on are small binary fractions).
    def geometry(cy2: float):
        K2 = np.array([[60.0, 0, 31.5], [0, 60.0, cy2], [0, 0, 1]])
        K1 = np.array([[60.0, 0, 31.5], [0, 60.0, 47.0], [0, 0, 1]])
        return rectified_geometry(Intrinsics(*SMALL, K1), np.eye(4), Intrinsics(*SMALL, K2),
                                  make_T(np.eye(3), [0.1, 0, 0]), depth_range=(1.0, 3.0))

    geom, _ = geometry(0.0)
    assert geom.size == (64, 1)
    with pytest.raises(StereoError, match="share no rows"):
        geometry(-1.0)


def test_a_capped_canvas_is_centred_on_the_left_image():
    # 40 deg from the optical axis the warped images are ~2600x2000 px; the canvas is capped at
    # 1.5 x 640 and cropped around the left image's centre. Camera 2 is tilted, so its centre
    # lands elsewhere.
    K = np.array([[600.0, 0, 319.5], [0, 600.0, 239.5], [0, 0, 1]])
    T2 = sideways(40.0) @ make_T(rot_x(math.radians(5.0)), np.zeros(3))
    img = np.zeros(SIZE[::-1], np.uint8)
    rp = rectify_pair(img, img, K, None, np.eye(4), K, None, T2)
    assert rp.size == (960, 960)
    centre = np.array([[(SIZE[0] - 1) / 2.0, (SIZE[1] - 1) / 2.0]])
    assert np.allclose(apply_h(rp.rectification.H1, centre), [[479.5, 479.5]], atol=1e-6)


@pytest.mark.parametrize("out_size", [(0, 48), (64, 0), (-3, 48)])
def test_a_forced_canvas_of_no_pixels_is_refused(out_size):
    intr = Intrinsics(*SMALL, K_SMALL)
    with pytest.raises(StereoError, match="out_size must be positive"):
        rectified_geometry(intr, np.eye(4), intr, sideways(90.0), out_size=out_size)


def test_a_single_channel_image_is_rectified_like_the_grey_one():
    rng = np.random.default_rng(3)
    a, b = (rng.integers(0, 256, SMALL[::-1], dtype=np.uint8) for _ in range(2))
    T2 = sideways(80.0, 0.05)
    grey = rectify_pair(a, b, K_SMALL, None, np.eye(4), K_SMALL, None, T2)
    one = rectify_pair(a[:, :, None], b[:, :, None], K_SMALL, None, np.eye(4), K_SMALL, None, T2)
    assert np.array_equal(one.left.reshape(grey.left.shape), grey.left)
    assert np.array_equal(one.right.reshape(grey.right.shape), grey.right)


@pytest.mark.parametrize("image_angle_deg", [0.0, 30.0, -60.0, 89.0, 90.0])
def test_reported_rotation_is_the_turn_of_the_left_images_rows(image_angle_deg):
    """View 2 seen at ``image_angle_deg`` in view 1's image (y down): the rectified image turns by
    minus that angle, so the baseline becomes its x axis; 0 reads as 0.0, not -0.0."""
    a = math.radians(image_angle_deg)
    T2 = make_T(np.eye(3), [0.1 * math.cos(a), 0.1 * math.sin(a), 0.0])
    img = np.zeros(SMALL[::-1], np.uint8)
    rp = rectify_pair(img, img, K_SMALL, None, np.eye(4), K_SMALL, None, T2)
    assert not rp.swapped
    assert rp.rotation_deg == pytest.approx(-image_angle_deg, abs=1e-9)
    row = apply_h(rp.rectification.H1, np.array([[10.0, 20.0], [30.0, 20.0]]))
    turn = math.degrees(math.atan2(*(row[1] - row[0])[::-1]))
    assert rp.rotation_deg == pytest.approx(turn, abs=1e-9)
    if image_angle_deg == 0.0:
        assert math.copysign(1.0, rp.rotation_deg) == 1.0
