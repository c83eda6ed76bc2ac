"""Scoring: exact point-to-triangle distances, thinning, DTU/ETH3D numbers on known offsets."""

import numpy as np
import pytest

from armstereo.errors import ConfigError
from armstereo.evaluation.scene_truth import SceneTruth, TruthPrimitive
from armstereo.fusion.mesh import Mesh
from armstereo.fusion.metrics import (
    Reference,
    mesh_distance,
    point_accuracy,
    point_triangle_distance,
    score_mesh,
    thin,
)
from armstereo.transforms import make_T


def _brute_force(p, a, b, c, n=200):
    """Distance to a dense grid of points on the triangle (an upper bound, close to exact)."""
    s, t = np.meshgrid(np.linspace(0, 1, n), np.linspace(0, 1, n))
    keep = s + t <= 1
    q = a + s[keep, None] * (b - a) + t[keep, None] * (c - a)
    return np.linalg.norm(q - p, axis=1).min()


def test_point_triangle_distance_matches_brute_force():
    rng = np.random.default_rng(3)
    for _ in range(60):
        a, b, c = rng.normal(size=(3, 3))
        p = rng.normal(size=3) * 2
        exact = point_triangle_distance(p, a, b, c)
        approx = _brute_force(p, a, b, c)
        assert exact <= approx + 1e-12
        assert approx - exact < 0.03  # the grid's spacing


def test_point_triangle_distance_on_features():
    a, b, c = np.array([0.0, 0, 0]), np.array([1.0, 0, 0]), np.array([0.0, 1, 0])
    assert point_triangle_distance(np.array([0.2, 0.2, 0.5]), a, b, c) == pytest.approx(0.5)
    assert point_triangle_distance(np.array([-1.0, -1, 0]), a, b, c) == pytest.approx(2**0.5)
    assert point_triangle_distance(np.array([1.0, 1, 0]), a, b, c) == pytest.approx(0.5**0.5)
    # degenerate triangles (repeated corners, as marching cubes can leave in float32) still
    # give the distance to what is left of them
    p = np.array([0.5, 1, 0])
    for tri in ((a, b, b), (a, a, b), (b, a, a), (a, b, a), (a, a, a)):
        expected = 1.0 if not np.array_equal(tri[0], tri[1]) or not np.array_equal(
            tri[1], tri[2]) else np.hypot(0.5, 1.0)
        assert point_triangle_distance(p, *tri) == pytest.approx(expected)
    rng = np.random.default_rng(5)
    for _ in range(30):  # random points against an edge-collapsed triangle: no error, exact
        q = rng.normal(size=3)
        assert point_triangle_distance(q, a, a, b) == pytest.approx(_brute_force(q, a, a, b),
                                                                    abs=0.01)


def _grid_mesh(z: float, half: float = 0.1, step: float = 0.002) -> Mesh:
    n = int(round(2 * half / step)) + 1
    x, y = np.meshgrid(np.linspace(-half, half, n), np.linspace(-half, half, n), indexing="ij")
    v = np.stack([x.ravel(), y.ravel(), np.full(x.size, z)], axis=1)
    i, j = np.meshgrid(np.arange(n - 1), np.arange(n - 1), indexing="ij")
    k = (i * n + j).ravel()
    faces = np.concatenate([np.stack([k, k + n, k + 1], 1), np.stack([k + 1, k + n, k + n + 1], 1)])
    return Mesh(v, faces, np.zeros((len(v), 3), np.uint8))


def _table_truth(half: float = 0.3) -> SceneTruth:
    return SceneTruth([TruthPrimitive("table", "rectangle", make_T(np.eye(3), (0, 0, 0)),
                                      (half, half))], support="table")


def test_mesh_distance_is_exact_for_points_over_the_mesh():
    mesh = _grid_mesh(0.0)
    rng = np.random.default_rng(1)
    pts = np.column_stack([rng.uniform(-0.09, 0.09, (500, 2)), rng.uniform(-0.01, 0.01, 500)])
    d = mesh_distance(mesh.vertices[mesh.faces].astype(float), pts)
    np.testing.assert_allclose(d, np.abs(pts[:, 2]), atol=1e-7)


def test_score_of_a_shifted_plane():
    # A mesh 1.5 mm above the true table: accuracy 1.5 mm everywhere, completeness 1.5 mm for
    # the reference under it and more for the reference beyond its edge.
    mesh = _grid_mesh(0.0015)
    xy = np.stack(np.meshgrid(np.linspace(-0.08, 0.08, 81), np.linspace(-0.08, 0.08, 81)),
                  -1).reshape(-1, 2)
    under = np.column_stack([xy, np.zeros(len(xy))])
    beyond = np.column_stack([xy[:100] * 0 + [0.2, 0.0], np.zeros(100)])  # 10 cm off the edge
    ref = Reference.from_sets(under, beyond)
    assert ref.stereo.sum() == len(under) and len(ref.points) == len(under) + 1  # thinned
    s = score_mesh(mesh, _table_truth(), ref)
    assert s.accuracy_mean_mm == pytest.approx(1.5, abs=1e-4)
    assert (s.within_1mm, s.within_2mm, s.within_5mm) == (0.0, 1.0, 1.0)
    assert s.completeness_mean_mm == pytest.approx(1.5, abs=1e-4)
    assert (s.completeness_within_1mm, s.completeness_within_2mm) == (0.0, 1.0)
    assert s.f1_2mm == 1.0 and s.f1_1mm == 0.0
    assert s.visible_surface_covered == pytest.approx(len(under) / (len(under) + 1))
    assert s.chamfer_mm == pytest.approx(1.5, abs=1e-4)


def test_accuracy_mean_leaves_out_far_outliers_but_counts_them():
    truth = _table_truth()
    pts = np.array([[0, 0, 0.001]] * 9 + [[0, 0, 0.1]])
    acc = point_accuracy(pts, truth)
    assert acc.accuracy_mean_mm == pytest.approx(1.0)
    assert acc.outliers == pytest.approx(0.1)
    assert acc.within_2mm == pytest.approx(0.9)


def test_weights_make_accuracy_an_area_integral():
    truth = _table_truth()
    pts = np.array([[0, 0, 0.001], [0, 0, 0.003]])
    assert point_accuracy(pts, truth, weights=[3.0, 1.0]).accuracy_mean_mm == pytest.approx(1.5)
    with pytest.raises(ConfigError):
        point_accuracy(pts, truth, weights=[1.0])


def test_thin_keeps_one_point_per_cell():
    pts = np.array([[0.0001, 0, 0], [0.0002, 0, 0], [0.0011, 0, 0], [0.0, 0.0015, 0]])
    out = thin(pts, 0.001)
    np.testing.assert_array_equal(out, pts[[0, 2, 3]])
    assert thin(np.zeros((0, 3)), 0.001).shape == (0, 3)


def test_reference_prefers_stereo_points_per_cell():
    stereo = np.array([[0.0005, 0, 0], [0.0105, 0, 0]])
    other = np.array([[0.0004, 0, 0], [0.0204, 0, 0]])  # first shares stereo[0]'s cell
    ref = Reference.from_sets(stereo, other, spacing=0.001)
    np.testing.assert_array_equal(ref.points, [stereo[0], stereo[1], other[1]])
    assert ref.stereo.tolist() == [True, True, False]
    np.testing.assert_array_equal(ref.stereo_points, stereo)


def test_score_needs_a_reference_and_a_mesh():
    nothing = Reference.from_sets(np.zeros((0, 3)), np.zeros((1, 3)))
    with pytest.raises(ConfigError, match="visible true surface"):
        score_mesh(_grid_mesh(0.0), _table_truth(), nothing)
    with pytest.raises(ConfigError, match="empty"):
        score_mesh(Mesh.empty(), _table_truth(), Reference.from_sets(np.zeros((1, 3)), []))
