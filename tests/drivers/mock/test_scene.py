"""The mock camera's ray-cast scene: exact intersections, world-fixed textures, lens distortion,
the default table scene and the sweep's planar targets."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from armstereo.camera_model import Intrinsics
from armstereo.errors import ConfigError
from armstereo.transforms import invert, make_T, rot_x, rot_z
from drivers.mock.scene import (
    SCENE_CENTER,
    Box,
    Cylinder,
    Rectangle,
    Scene,
    Sphere,
    Texture,
    default_table_scene,
    planar_target_scene,
)

TEX = Texture((40, 40, 40), (220, 220, 220), seed=1)
# Camera optical frame looking straight down: image x = base +y, image y = base +x.
R_DOWN = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])
SMALL = Intrinsics(160, 120, np.array([[150.0, 0, 79.5], [0, 150.0, 59.5], [0, 0, 1]]))
VGA = Intrinsics(640, 480, np.array([[600.0, 0, 319.5], [0, 600.0, 239.5], [0, 0, 1]]))


def down_camera(x: float, y: float, z: float) -> np.ndarray:
    return make_T(R_DOWN, (x, y, z))


def table_only(half=(2.0, 2.0)) -> Scene:
    return Scene([Rectangle(np.eye(4), *half, TEX, name="table")])


def test_rectangle_hit_is_exact_and_bounded():
    scene = table_only(half=(0.5, 0.3))
    d = np.array([[0.1, -0.2, -1.0], [0.0, 0.0, -1.0], [1.0, 0.0, -1.0], [0.0, 0.0, 1.0]])
    t, idx = scene.intersect((0.0, 0.0, 0.55), d)
    assert t[0] == pytest.approx(0.55, abs=1e-15) and t[1] == pytest.approx(0.55, abs=1e-15)
    assert list(idx) == [0, 0, -1, -1]  # x = 0.55 is beyond half_x; the last ray looks up
    assert np.isinf(t[2]) and np.isinf(t[3])


def test_box_hits_faces_and_rotated_corner():
    box = Box((0.0, 0.0, 0.05), (0.2, 0.1, 0.1), TEX)
    scene = Scene([box])
    t, idx = scene.intersect((0.0, 0.0, 1.0), [[0, 0, -1]])
    assert t[0] == pytest.approx(0.9, abs=1e-12) and idx[0] == 0
    t, _ = scene.intersect((-1.0, 0.0, 0.05), [[1, 0, 0], [0, 1, 0]])
    assert t[0] == pytest.approx(0.9, abs=1e-12) and np.isinf(t[1])
    assert np.allclose(box.normals(np.array([[-0.1], [0.0], [0.05]])).ravel(), [-1, 0, 0])
    assert np.allclose(box.normals(np.array([[0.0], [0.02], [0.1]])).ravel(), [0, 0, 1])
    # Rotated 45 deg about z: a ray along x through the centre meets the vertical edge.
    turned = Scene([Box((0.0, 0.0, 0.05), (0.2, 0.2, 0.1), TEX, yaw=np.pi / 4)])
    t, _ = turned.intersect((-1.0, 0.0, 0.05), [[1, 0, 0]])
    assert t[0] == pytest.approx(1.0 - 0.1 * np.sqrt(2), abs=1e-12)


def test_cylinder_hits_caps_and_side():
    cyl = Cylinder((0.3, 0.0), 0.05, 0.1, TEX)
    scene = Scene([cyl])
    t, idx = scene.intersect((0.3, 0.0, 1.0), [[0, 0, -1]])
    assert t[0] == pytest.approx(0.9, abs=1e-12) and idx[0] == 0
    tangent = 0.05 / np.sqrt(0.3**2 - 0.05**2)  # slope of the ray grazing the side
    dirs = [[1, 0, 0], [1, tangent * 1.001, 0], [1, tangent * 0.999, 0]]
    t, idx = scene.intersect((0.0, 0.0, 0.05), dirs)
    assert t[0] == pytest.approx(0.25, abs=1e-12)
    assert idx[1] == -1 and idx[2] == 0
    t, _ = scene.intersect((0.0, 0.0, 0.2), [[1, 0, 0]])  # above it
    assert np.isinf(t[0])
    # Slanted ray entering through the top cap near the rim.
    t, _ = scene.intersect((0.3 + 0.04, 0.0, 0.3), [[0.0, 0.0, -1.0]])
    assert t[0] == pytest.approx(0.2, abs=1e-12)
    n = cyl.normals(np.array([[0.25, 0.3], [0.0, 0.0], [0.05, 0.1]]))
    assert np.allclose(n.T, [[-1, 0, 0], [0, 0, 1]])


def test_sphere_hits_front_and_grazing_rays():
    sph = Sphere((0.0, 0.0, 0.1), 0.05, TEX)
    scene = Scene([sph])
    off = 0.03  # ray offset from the centre: hits at depth sqrt(r^2 - off^2) before centre
    t, idx = scene.intersect((0.0, off, 1.0), [[0, 0, -1], [0, 0, 1]])
    assert t[0] == pytest.approx(0.9 - np.sqrt(0.05**2 - off**2), abs=1e-12)
    assert idx[0] == 0 and idx[1] == -1
    t, _ = scene.intersect((0.0, 0.0501, 1.0), [[0, 0, -1]])
    assert np.isinf(t[0])
    assert np.allclose(sph.normals(np.array([[0.0], [0.0], [0.15]])).ravel(), [0, 0, 1])


def test_nearest_primitive_wins():
    scene = Scene([Rectangle(np.eye(4), 1, 1, TEX), Box((0, 0, 0.05), (0.1, 0.1, 0.1), TEX)])
    t, idx = scene.intersect((0.0, 0.0, 1.0), [[0, 0, -1], [0.2, 0, -1]])
    assert list(idx) == [1, 0]
    assert t[0] == pytest.approx(0.9) and t[1] == pytest.approx(1.0)


def test_depth_of_the_table_is_exact_from_a_tilted_camera():
    # Camera 0.6 m up, tilted 25 deg: z-depth of the plane z = 0 at each pixel is
    # h / (n_c . ray) with n_c the table normal in the camera frame.
    T = make_T(R_DOWN @ rot_x(np.radians(25)), (0.0, 0.0, 0.6))
    _, depth = table_only().render(T, SMALL, supersample=1)
    u, v = np.meshgrid(np.arange(160), np.arange(120))
    rays = np.stack([(u - 79.5) / 150, (v - 59.5) / 150, np.ones_like(u, float)], axis=-1)
    n_c = T[:3, :3].T @ np.array([0, 0, 1.0])
    expected = -0.6 / (rays @ n_c)
    expected[expected <= 0] = np.nan
    np.testing.assert_allclose(depth, expected, rtol=2e-6)
    assert depth.dtype == np.float32


def test_texture_is_fixed_to_the_world_integer_disparity():
    # Looking straight down at the plane from 0.55 m, a camera shift of b along image x moves
    # every table point by f b / Z = 12 px: the images must agree exactly after that shift.
    scene = table_only()
    b = 12 * 0.55 / 150
    left, dl = scene.render(down_camera(0, 0, 0.55), SMALL)
    right, _ = scene.render(down_camera(0, b, 0.55), SMALL)  # image x = base +y
    assert np.all(dl == np.float32(0.55))
    diff = np.abs(left[:, 12:].astype(int) - right[:, :-12].astype(int))
    assert diff.max() <= 1
    assert np.abs(left[:, 12:].astype(int) - left[:, :-12].astype(int)).mean() > 20


def test_texture_is_fixed_to_the_world_general_views():
    # The same surface points reached from two camera centres have the same colour...
    scene = default_table_scene()
    cx, cy = SCENE_CENTER
    rng = np.random.default_rng(3)
    targets = np.column_stack([cx + rng.uniform(-0.2, 0.2, 500), cy + rng.uniform(-0.2, 0.2, 500),
                               np.full(500, 0.5)])
    o1, o2 = np.array([cx, cy, 0.55]), np.array([cx + 0.1, cy - 0.15, 0.5])
    t1, i1 = scene.intersect(o1, targets - o1 - [0, 0, 0.6])
    p = o1 + t1[:, None] * (targets - o1 - [0, 0, 0.6])
    t2, i2 = scene.intersect(o2, p - o2)
    visible = (i1 >= 0) & (i2 == i1) & (np.abs(t2 - 1.0) < 1e-9)
    assert visible.sum() > 300
    p2 = o2 + t2[visible, None] * (p[visible] - o2)
    np.testing.assert_allclose(scene.surface_color(p2, i2[visible]),
                               scene.surface_color(p[visible], i1[visible]), atol=1e-3)
    # ... and rendered images agree where one view reprojects into the other.
    T1 = down_camera(cx, cy, 0.55)
    T2 = make_T(R_DOWN @ rot_x(0.15) @ rot_z(0.3), (cx + 0.05, cy + 0.08, 0.6))
    img1, d1 = scene.render(T1, VGA)
    img2, d2 = scene.render(T2, VGA)
    v, u = np.mgrid[0:480:3, 0:640:3]
    z = d1[v, u]
    X1 = np.stack([(u - 319.5) / 600 * z, (v - 239.5) / 600 * z, z], -1).reshape(-1, 3)
    X2 = X1 @ (invert(T2) @ T1)[:3, :3].T + (invert(T2) @ T1)[:3, 3]
    u2, v2 = X2[:, 0] / X2[:, 2] * 600 + 319.5, X2[:, 1] / X2[:, 2] * 600 + 239.5
    inside = np.isfinite(z.ravel()) & (u2 > 2) & (u2 < 637) & (v2 > 2) & (v2 < 477)
    r2, c2 = np.rint(v2[inside]).astype(int), np.rint(u2[inside]).astype(int)
    seen = np.abs(d2[r2, c2] - X2[inside, 2]) < 1e-3  # not occluded in view 2
    m = np.flatnonzero(inside)[seen]
    sample = cv2.remap(img2, u2[m].astype(np.float32).reshape(1, -1),
                       v2[m].astype(np.float32).reshape(1, -1), cv2.INTER_LINEAR).reshape(-1, 3)
    err = np.abs(sample.astype(float) - img1[v, u].reshape(-1, 3)[m])
    assert len(m) > 20000
    assert np.median(err) <= 2.0 and np.percentile(err, 90) < 12  # bilinear resampling only


def test_texture_is_band_limited_and_contrasted():
    # docs/birchfield-tomasi.md §9.1: no per-pixel white noise. At 0.55 m (f = 600 px) almost no
    # energy may sit above 0.25 cycles/px, and the texture must have strong contrast.
    img, _ = table_only().render(down_camera(0, 0, 0.55), VGA)
    g = cv2.cvtColor(img, cv2.COLOR_BGR2GRAY).astype(float)
    assert g.std() > 35
    spec = np.abs(np.fft.fft2(g - g.mean())) ** 2
    f = np.hypot(*np.meshgrid(np.fft.fftfreq(640), np.fft.fftfreq(480)))
    assert spec[f > 0.25].sum() / spec.sum() < 0.01
    grad = np.abs(np.diff(g, axis=1))
    assert np.median(grad) > 3  # but not flat either: horizontal gradients for matching


def test_distortion_bends_a_straight_edge_like_opencv():
    dist = np.array([-0.25, 0.08, 0.0, 0.0, 0.0])
    intr = Intrinsics(320, 240, np.array([[300.0, 0, 159.5], [0, 300.0, 119.5], [0, 0, 1]]),
                      dist)
    pinhole = Intrinsics(320, 240, intr.K)
    # A plane ending at base x = 0.35: one edge, crossing the image near its bottom.
    scene = Scene([Rectangle(make_T(np.eye(3), (-1.0, 0.0, 0.0)), 1.35, 2.0, TEX)])
    T = down_camera(0.0, 0.0, 1.0)  # image y = base x: the edge is a row near the bottom
    edges = {}
    for name, k in (("pinhole", pinhole), ("distorted", intr)):
        _, depth = scene.render(T, k, supersample=1)
        covered = np.isfinite(depth)
        edges[name] = covered.sum(axis=0).astype(float)  # rows covered per column, from the top
    cols = np.arange(20, 300)

    def off_line(rows):  # largest deviation (px) from the best straight line
        return np.max(np.abs(rows - np.polyval(np.polyfit(cols, rows, 1), cols)))

    assert off_line(edges["pinhole"][cols]) < 0.5
    assert off_line(edges["distorted"][cols]) > 2.0
    # Where OpenCV projects the edge, the rendered coverage ends (within a pixel).
    y_edge = np.linspace(-0.6, 0.6, 4001)
    pts = np.column_stack([y_edge, np.full_like(y_edge, 0.35), np.full_like(y_edge, 1.0)])
    uv, _ = cv2.projectPoints(pts, np.zeros(3), np.zeros(3), intr.K, dist)
    uv = uv.reshape(-1, 2)
    v_proj = np.interp(cols, uv[:, 0], uv[:, 1])
    assert np.max(np.abs(edges["distorted"][cols] - np.ceil(v_proj))) <= 1.0


def test_distorted_render_puts_objects_where_opencv_projects_them():
    dist = np.array([-0.3, 0.1, 0.001, -0.0005, 0.0])
    intr = Intrinsics(320, 240, np.array([[300.0, 0, 159.5], [0, 300.0, 119.5], [0, 0, 1]]),
                      dist)
    centres = np.array([[0.0, 0.0, 0.02], [0.2, 0.3, 0.02], [-0.2, -0.3, 0.02],
                        [0.22, -0.3, 0.02]])
    scene = Scene([Rectangle(np.eye(4), 2, 2, TEX)] + [Sphere(c, 0.012, TEX) for c in centres])
    T = down_camera(0.0, 0.0, 0.6)
    _, depth = scene.render(T, intr, supersample=1)
    on_sphere = depth < 0.59
    T_cb = invert(T)
    uv, _ = cv2.projectPoints(centres @ T_cb[:3, :3].T + T_cb[:3, 3], np.zeros(3), np.zeros(3),
                              intr.K, dist)
    uv_pin, _ = cv2.projectPoints(centres @ T_cb[:3, :3].T + T_cb[:3, 3], np.zeros(3),
                                  np.zeros(3), intr.K, None)
    n, labels = cv2.connectedComponents(on_sphere.astype(np.uint8))
    assert n - 1 == len(centres)
    found = []
    for lab in range(1, n):
        rr, cc = np.nonzero(labels == lab)
        found.append((cc.mean(), rr.mean()))
    found = np.array(found)
    for k, (p, q) in enumerate(zip(uv.reshape(-1, 2), uv_pin.reshape(-1, 2), strict=True)):
        # Each blob is centred where OpenCV projects its sphere's centre, with distortion...
        assert np.linalg.norm(found - p, axis=1).min() < 0.5
        if k > 0:  # ... which moves the off-centre ones far from the pinhole projection
            assert np.linalg.norm(p - q) > 10


def test_default_table_scene_objects_heights_and_view():
    scene = default_table_scene()
    names = [p.name for p in scene.primitives]
    assert names[0] == "table" and names[-1] == "floor" and 5 <= len(names) - 2 <= 8
    tops = [p.corners_base()[:, 2].max() for p in scene.primitives[1:-1]]
    assert min(tops) >= 0.02 and max(tops) <= 0.15 + 1e-9 and len(set(np.round(tops, 3))) >= 5
    bottoms = [p.corners_base()[:, 2].min() for p in scene.primitives[1:-1]]
    assert np.allclose(bottoms, 0.0)  # everything stands on the table
    img, depth = scene.render(down_camera(*SCENE_CENTER, 0.55), VGA)
    assert np.all(np.isfinite(depth))  # the table fills the view
    assert np.nanmin(depth) == pytest.approx(0.40, abs=1e-6)  # top of the 15 cm can
    # Every object is in view: its top shows at the exact depth where it projects.
    for prim in scene.primitives[1:-1]:
        x, y = prim.T_base_local[:2, 3]
        top = prim.corners_base()[:, 2].max()
        u = 319.5 + 600 * (y - SCENE_CENTER[1]) / (0.55 - top)
        v = 239.5 + 600 * (x - SCENE_CENTER[0]) / (0.55 - top)
        assert depth[round(v), round(u)] == pytest.approx(0.55 - top, abs=1e-4), prim.name
    again, _ = default_table_scene().render(down_camera(*SCENE_CENTER, 0.55), VGA)
    other, _ = default_table_scene(seed=1).render(down_camera(*SCENE_CENTER, 0.55), VGA)
    assert np.array_equal(img, again) and not np.array_equal(img, other)


def test_planar_targets_have_true_depths_and_stay_visible():
    distances = [0.8, 2.2, 1.0, 1.4, 1.7, 2.0, 1.2]
    T = make_T(rot_x(-np.pi / 2), (0.3, -0.2, 0.5))  # looking horizontally along base +y
    scene, targets = planar_target_scene(distances, T, VGA, max_baseline=0.3)
    assert [t.distance for t in targets] == distances and [t.index for t in targets] == list(
        range(7))
    T_right = T @ make_T(np.eye(3), (0.3, 0.0, 0.0))
    _, d_left = scene.render(T, VGA, supersample=1)
    _, d_right = scene.render(T_right, VGA, supersample=1)
    for tgt in targets:
        for T_cam, depth in ((T, d_left), (T_right, d_right)):
            u0, v0, u1, v1 = tgt.pixel_box_in(T_cam, VGA)
            assert u0 > 10 and v0 > 10 and u1 < 629 and v1 < 469  # well inside the view
            patch = depth[int(np.ceil(v0)) + 1:int(v1), int(np.ceil(u0)) + 1:int(u1)]
            assert patch.size > 1500
            np.testing.assert_allclose(patch, tgt.distance, rtol=1e-5)
        assert tgt.pixel_box == tgt.pixel_box_in(T, VGA)
    with pytest.raises(ConfigError, match="distances"):
        planar_target_scene([1.0, -1.0], T, VGA)
    with pytest.raises(ConfigError, match="px per target"):
        planar_target_scene(np.linspace(0.8, 2.2, 200), T, VGA, max_baseline=0.3)


def test_bad_inputs_are_config_errors():
    scene = table_only()
    with pytest.raises(ConfigError):
        scene.render(np.eye(3), SMALL)
    bad = np.eye(4)
    bad[0, 0] = 2.0
    with pytest.raises(ConfigError):
        scene.render(bad, SMALL)
    with pytest.raises(ConfigError):
        scene.render(np.eye(4), SMALL, supersample=0)
    with pytest.raises(ConfigError):
        Box((0, 0, 0), (0.1, -0.1, 0.1), TEX)
    with pytest.raises(ConfigError):
        Scene([])
