"""Scene truth: exact distances agree with the mock ray caster, objects with the scene table."""

import json

import numpy as np
import pytest

from armstereo.errors import ConfigError
from armstereo.evaluation.scene_truth import SceneTruth, TruthPrimitive
from armstereo.transforms import make_T, rot_z
from drivers.mock.scene import default_table_scene


def test_ray_hits_lie_on_the_true_surface():
    scene = default_table_scene(0)
    truth = scene.truth()
    rng = np.random.default_rng(1)
    origin = np.array([-0.45, -0.13, 0.55])
    dirs = np.column_stack([rng.uniform(-0.5, 0.5, 4000), rng.uniform(-0.5, 0.5, 4000),
                            -np.ones(4000)])
    t, idx = scene.intersect(origin, dirs)
    hit = np.isfinite(t)
    points = origin + t[hit, None] * dirs[hit]
    assert hit.mean() > 0.99
    assert truth.distance(points).max() < 1e-9
    # Points lifted 2 mm along the ray's reverse are 2 mm (or less, at slanted hits) away.
    lifted = points - 0.002 * dirs[hit] / np.linalg.norm(dirs[hit], axis=1, keepdims=True)
    d = truth.distance(lifted)
    assert d.max() <= 0.002 + 1e-9 and np.median(d) > 0.0015


@pytest.mark.parametrize("kind,dims,point,expected", [
    ("box", (0.2, 0.1, 0.06), (0.0, 0.0, 0.0), 0.03),      # centre: nearest face 3 cm away
    ("box", (0.2, 0.1, 0.06), (0.13, 0.08, 0.0), np.hypot(0.03, 0.03)),  # outside a vertical edge
    ("cylinder", (0.05, 0.1), (0.0, 0.0, 0.05), 0.05),     # on the axis, half height
    ("cylinder", (0.05, 0.1), (0.08, 0.0, 0.14), 0.05),    # beyond the rim of the top cap
    ("sphere", (0.04,), (0.0, 0.07, 0.0), 0.03),
    ("rectangle", (0.3, 0.2), (0.34, 0.0, 0.03), 0.05),
])
def test_exact_distances(kind, dims, point, expected):
    p = TruthPrimitive("p", kind, make_T(np.eye(3), (1.0, 2.0, 0.5)), dims)
    d = p.distance(np.array(point) + (1.0, 2.0, 0.5))
    assert d == pytest.approx([expected], abs=1e-12)


def test_objects_follow_the_table_layout():
    truth = default_table_scene(0).truth()
    objects = {o.name: o for o in truth.objects()}
    assert set(objects) == {"crate", "book", "can", "puck", "ball", "block", "marble"}
    crate = objects["crate"]
    assert crate.size_m == pytest.approx((0.12, 0.08, 0.10))
    assert crate.height_m == pytest.approx(0.10)
    assert crate.yaw_deg == pytest.approx(np.degrees(0.3))
    can = objects["can"]
    assert can.size_m == pytest.approx((0.07, 0.07, 0.15)) and can.height_m == pytest.approx(0.15)
    assert can.center_m[2] == pytest.approx(0.075)
    assert objects["ball"].height_m == pytest.approx(0.09)


def test_box_longer_along_y_reports_length_axis_yaw():
    box = TruthPrimitive("b", "box", make_T(rot_z(0.2), (0, 0, 0.05)), (0.05, 0.15, 0.1))
    (obj,) = SceneTruth([box]).objects()
    assert obj.size_m == pytest.approx((0.15, 0.05, 0.1))
    assert obj.yaw_deg == pytest.approx(np.degrees(0.2) + 90.0 - 180.0)


def test_json_round_trip_and_errors():
    truth = default_table_scene(3).truth()
    again = SceneTruth.from_json(truth.to_json())
    pts = np.random.default_rng(0).uniform(-1, 1, (100, 3))
    assert np.array_equal(again.distance(pts), truth.distance(pts))
    assert again.support == "table"
    with pytest.raises(ConfigError, match="malformed"):
        SceneTruth.from_json("{}")
    bad = json.loads(truth.to_json())
    bad["primitives"][1]["dims"] = [0.1]
    with pytest.raises(ConfigError, match="needs 3 positive dims"):
        SceneTruth.from_json(json.dumps(bad))
