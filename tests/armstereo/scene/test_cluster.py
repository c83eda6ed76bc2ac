"""Voxel connected components: separate what is apart, join what touches, drop sparse noise;
the same partition as scikit-learn's DBSCAN on a tabletop's object points."""

from __future__ import annotations

import numpy as np
import pytest

from armstereo.scene.cluster import (
    NOISE,
    merge_covered,
    merge_split_tops,
    split_bridged,
    split_valleys,
    voxel_clusters,
)
from armstereo.scene.synthetic import default_truth, scan


def _patch(centre, half, spacing=0.001):
    """A level square of grid points (like an object's top face seen from above), placed so
    that no voxel holds a lone corner point."""
    g = np.arange(-half, half - 1e-9, spacing) + 0.0002
    x, y = np.meshgrid(g, g)
    return np.column_stack([x.ravel(), y.ravel(), np.zeros(x.size)]) + centre


def test_two_patches_apart_are_two_clusters_numbered_by_size():
    small, big = _patch((0, 0, 0.05), 0.01), _patch((0.1, 0, 0.03), 0.02)
    labels = voxel_clusters(np.vstack([small, big]), 0.005)
    assert np.all(labels[len(small):] == 0) and np.all(labels[:len(small)] == 1)


def test_patches_closer_than_a_voxel_join_and_farther_ones_do_not():
    a = _patch((0, 0, 0), 0.01)
    assert len(set(voxel_clusters(np.vstack([a, _patch((0.023, 0, 0), 0.01)]), 0.005))) == 1
    assert len(set(voxel_clusters(np.vstack([a, _patch((0.032, 0, 0), 0.01)]), 0.005))) == 2


def test_isolated_points_and_small_clusters_are_noise():
    rng = np.random.default_rng(2)
    patch = _patch((0, 0, 0), 0.02)
    strays = rng.uniform(0.2, 0.5, (30, 3))  # one point per voxel: below min_voxel_points
    small = _patch((-0.2, 0, 0), 0.002)  # 25 points
    labels = voxel_clusters(np.vstack([patch, strays, small]), 0.005, min_voxel_points=2,
                            min_cluster_points=50)
    assert np.all(labels[:len(patch)] == 0)
    assert np.all(labels[len(patch):] == NOISE)


def test_far_outliers_cost_nothing_and_empty_input_is_fine():
    pts = np.vstack([_patch((0, 0, 0), 0.01), [[1000.0, -500.0, 20.0]] * 3])
    labels = voxel_clusters(pts, 0.005)
    assert labels[-1] == 1 and labels[0] == 0
    assert voxel_clusters(np.zeros((0, 3)), 0.005).shape == (0,)
    with pytest.raises(ValueError):
        voxel_clusters(pts, 0.0)


def test_same_partition_as_sklearn_dbscan_on_tabletop_objects():
    sklearn_cluster = pytest.importorskip("sklearn.cluster")
    from sklearn.metrics import adjusted_rand_score

    cloud = scan(default_truth(), spacing=0.0015, noise=0.0005)
    objects = cloud.points[cloud.points[:, 2] > 0.005]
    ours = voxel_clusters(objects, 0.005, min_voxel_points=2, min_cluster_points=50)
    ref = sklearn_cluster.DBSCAN(eps=0.005, min_samples=10).fit_predict(objects)
    assert set(ours) - {NOISE} == set(ref) - {NOISE} == {0, 1, 2, 3}
    assert np.mean(ours == NOISE) < 0.001
    both = (ours != NOISE) & (ref != NOISE)
    assert adjusted_rand_score(ref[both], ours[both]) == pytest.approx(1.0)


def _square(x0: float, y0: float, side: float, spacing: float = 0.002) -> np.ndarray:
    g = np.arange(0.0, side, spacing)
    u, v = np.meshgrid(x0 + g, y0 + g)
    return np.column_stack([u.ravel(), v.ravel()])


def test_two_objects_joined_by_a_narrow_bridge_are_split():
    a, b = _square(0.0, 0.0, 0.06), _square(0.1, 0.0, 0.06)
    bridge = _square(0.06, 0.025, 0.04)
    bridge = bridge[bridge[:, 1] < 0.035]  # 1 cm wide, 4 cm long
    uv = np.vstack([a, b, bridge])
    labels = split_bridged(uv, np.zeros(len(uv), dtype=np.int64), 0.005, 0.01, 0.02 ** 2)
    assert len(np.unique(labels)) == 2
    assert len(np.unique(labels[:len(a)])) == 1
    assert len(np.unique(labels[len(a):len(a) + len(b)])) == 1
    assert labels[0] != labels[len(a)]


def test_one_object_and_noise_labels_are_left_alone():
    uv = np.vstack([_square(0.0, 0.0, 0.08), _square(0.3, 0.3, 0.01)])
    labels = np.r_[np.zeros(1600, dtype=np.int64), np.full(len(uv) - 1600, NOISE)]
    assert np.array_equal(split_bridged(uv, labels, 0.005, 0.01, 0.02 ** 2), labels)


def _top(u0, v0, side_u, side_v, height, spacing=0.002):
    """(N, 3) plane points of a level top ``height`` above the plane."""
    u, v = np.meshgrid(np.arange(u0, u0 + side_u, spacing), np.arange(v0, v0 + side_v, spacing))
    return np.column_stack([u.ravel(), v.ravel(), np.full(u.size, height)])


def test_two_tops_over_a_wide_low_band_are_split_and_far_low_points_dropped():
    # a tray (15 mm) and a keypad (20 mm) 2 cm apart, the gap filled at 6 mm across its whole
    # 8 cm width (too wide for split_bridged), and a 2 mm sheet beyond the tray
    tray, keypad = _top(0.0, 0.0, 0.20, 0.14, 0.015), _top(0.0, 0.16, 0.08, 0.12, 0.020)
    gap, sheet = _top(0.0, 0.14, 0.08, 0.02, 0.006), _top(0.20, 0.0, 0.15, 0.14, 0.002)
    uvh = np.vstack([tray, keypad, gap, sheet])
    labels = split_valleys(uvh[:, :2], uvh[:, 2] > 0.01, np.zeros(len(uvh), dtype=np.int64),
                           0.005, 0.02 ** 2, 0.015)
    t, k = labels[:len(tray)], labels[len(tray):len(tray) + len(keypad)]
    assert len(np.unique(t)) == 1 and len(np.unique(k)) == 1 and t[0] != k[0] >= 0
    g = labels[len(tray) + len(keypad):len(tray) + len(keypad) + len(gap)]
    assert set(np.unique(g)) <= {t[0], k[0]}  # the gap goes to the nearer top
    far = uvh[:, 0] > 0.20 + 0.02  # more than 15 mm (and a cell) beyond the tray
    assert np.all(labels[far] == NOISE)
    assert np.all(labels[(uvh[:, 0] < 0.20) & (uvh[:, 2] > 0.01)] != NOISE)


def test_one_top_with_a_low_skirt_and_noise_labels_are_left_alone():
    top, skirt = _top(0.0, 0.0, 0.10, 0.10, 0.03), _top(0.10, 0.0, 0.10, 0.10, 0.004)
    uvh = np.vstack([top, skirt, _top(0.5, 0.5, 0.01, 0.01, 0.03)])
    labels = np.r_[np.zeros(len(top) + len(skirt), dtype=np.int64),
                   np.full(len(uvh) - len(top) - len(skirt), NOISE)]
    assert np.array_equal(split_valleys(uvh[:, :2], uvh[:, 2] > 0.01, labels, 0.005, 0.02 ** 2,
                                        0.015), labels)


def test_a_lower_part_within_an_objects_top_view_joins_it_and_nothing_else_does():
    top = _top(0.0, 0.0, 0.08, 0.08, 0.10)  # a pot's top, 10 cm high
    side = _top(0.0, 0.0, 0.06, 0.03, 0.05)  # its side, cut off in 3-D, under the top view
    blob = _top(0.02, 0.02, 0.04, 0.04, 0.14)  # a mismatch blob floating above it
    neighbour = _top(0.085, 0.0, 0.06, 0.06, 0.05)  # the next object, side by side
    uvh = np.vstack([top, side, blob, neighbour])
    labels = np.repeat(np.arange(4), [len(top), len(side), len(blob), len(neighbour)])
    merged = merge_covered(uvh, labels, 0.01, 0.5, 0.005)
    assert np.array_equal(np.unique(merged[:len(top) + len(side)]), [0])
    assert np.array_equal(merged[len(top) + len(side):], labels[len(top) + len(side):])
    # only the clusters that passed as objects take part
    assert np.array_equal(merge_covered(uvh, labels, 0.01, 0.5, 0.005, eligible=[0, 2, 3]),
                          labels)


def test_a_sliver_beside_a_top_at_the_same_height_joins_it():
    """A mug's rim seen as two arcs (a glossy top's lost highlight): one piece 25 mm wide
    beside another at the same height, a cell apart, is one object."""
    a = _top(0.0, 0.0, 0.07, 0.025, 0.090)
    b = _top(0.0, 0.035, 0.07, 0.03, 0.088)
    uvh = np.vstack([a, b])
    labels = np.repeat([0, 1], [len(a), len(b)])
    merged = merge_split_tops(uvh, labels, 0.01, 0.035, 0.005, 0.05)
    assert len(np.unique(merged)) == 1
    # not eligible (not objects): left alone
    assert np.array_equal(merge_split_tops(uvh, labels, 0.01, 0.035, 0.005, 0.05,
                                           eligible=[0]), labels)


def test_objects_side_by_side_stay_apart_unless_one_is_a_sliver_at_the_same_height():
    box = _top(0.0, 0.0, 0.08, 0.08, 0.06)  # 0..80 mm in u
    cases = {
        "two wide boxes, same height": _top(0.085, 0.0, 0.08, 0.08, 0.06),
        "a sliver, 2 cm higher": _top(0.085, 0.0, 0.025, 0.08, 0.08),
        "a sliver, 4 cm away": _top(0.12, 0.0, 0.025, 0.08, 0.06),
    }
    for name, other in cases.items():
        uvh = np.vstack([box, other])
        labels = np.repeat([0, 1], [len(box), len(other)])
        assert np.array_equal(merge_split_tops(uvh, labels, 0.01, 0.035, 0.005, 0.05),
                              labels), name
    sliver = _top(0.085, 0.0, 0.025, 0.08, 0.06)  # 5 mm away, same height: one object
    uvh = np.vstack([box, sliver])
    labels = np.repeat([0, 1], [len(box), len(sliver)])
    assert len(np.unique(merge_split_tops(uvh, labels, 0.01, 0.035, 0.005, 0.05))) == 1
