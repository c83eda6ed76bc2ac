"""Scan viewpoint planning: layouts, look-at geometry, kinematic filtering with reasons, order."""

import math

import numpy as np
import pytest

from armstereo.capture.plan import Workspace
from armstereo.capture.scan_plan import (
    LEVEL_ROLLS_DEG,
    ViewLayout,
    layout_directions,
    look_at_pose,
    order_tour,
    parse_views,
    plan_scan,
)
from armstereo.errors import ConfigError
from armstereo.mount import CameraMount
from armstereo.robot.arm_model import ArmModel
from drivers.mock.start_poses import table_start as mock_start_configuration

TARGET = np.array([-0.45, -0.13, 0.03])


@pytest.fixture(scope="module")
def model():
    return ArmModel.load("ur5e", mount=CameraMount.load(None))


@pytest.fixture(scope="module")
def ring_plan(model):
    return plan_scan(model, mock_start_configuration(model), TARGET, views="ring:8",
                     radius=0.45, elevation_deg=55.0, baseline=0.06)


@pytest.mark.parametrize("text,layout", [("ring:12", ViewLayout("ring", 1, 12)),
                                         ("Sphere:5", ViewLayout("sphere", 1, 5)),
                                         ("grid:2x6", ViewLayout("grid", 2, 6))])
def test_parse_views(text, layout):
    assert parse_views(text) == layout
    assert str(parse_views(str(layout))) == str(layout)


@pytest.mark.parametrize("text", ["ring", "ring:0", "ring:x", "grid:3", "cube:4", "ring:500"])
def test_parse_views_rejects(text):
    with pytest.raises(ConfigError, match="--views"):
        parse_views(text)


@pytest.mark.parametrize("az,el", [(0.0, 55.0), (2.0, 30.0), (4.0, 89.0), (1.0, 90.0),
                                   (5.0, 0.0)])
def test_look_at_pose_points_the_optical_axis_at_the_target(az, el):
    T = look_at_pose(TARGET, az, math.radians(el), 0.4)
    R = T[:3, :3]
    np.testing.assert_allclose(R.T @ R, np.eye(3), atol=1e-12)
    assert np.linalg.det(R) == pytest.approx(1.0)
    to_target = TARGET - T[:3, 3]
    assert np.linalg.norm(to_target) == pytest.approx(0.4)
    np.testing.assert_allclose(R[:, 2], to_target / 0.4, atol=1e-12)
    assert abs(R[2, 0]) < 1e-12  # camera x (the baseline) is horizontal
    assert R[2, 1] <= 1e-12  # camera y (image down) points down or level: image up is up
    assert T[2, 3] - TARGET[2] == pytest.approx(0.4 * math.sin(math.radians(el)))


def test_roll_turns_about_the_optical_axis():
    T0 = look_at_pose(TARGET, 1.0, 0.8, 0.4)
    T1 = look_at_pose(TARGET, 1.0, 0.8, 0.4, roll=math.pi)
    np.testing.assert_allclose(T1[:3, 2], T0[:3, 2], atol=1e-12)
    np.testing.assert_allclose(T1[:3, 0], -T0[:3, 0], atol=1e-12)


def test_layout_directions():
    ring = layout_directions(parse_views("ring:4"), 40.0)
    assert [round(math.degrees(a)) for a, _ in ring] == [0, 90, 180, 270]
    assert all(e == pytest.approx(math.radians(40)) for _, e in ring)
    sphere = layout_directions(parse_views("sphere:50"), 30.0)
    els = np.degrees([e for _, e in sphere])
    assert els.min() >= 30.0 and els.max() <= 90.0
    # even area on the cap: half the directions lie above the elevation that halves it
    s0 = math.sin(math.radians(30))
    half = math.degrees(math.asin((1 + s0) / 2))
    assert np.mean(els > half) == pytest.approx(0.5, abs=0.05)
    grid = layout_directions(parse_views("grid:3x4"), 20.0)
    assert len(grid) == 12
    assert sorted({round(math.degrees(e)) for _, e in grid}) == [20, 50, 80]


def test_kept_views_are_stereo_pairs_the_arm_reaches(model, ring_plan):
    assert len(ring_plan.views) + len(ring_plan.dropped) == 8
    assert len(ring_plan.views) >= 6
    for v in ring_plan.views:
        for q, T in ((v.q_left, v.T_base_left), (v.q_right, v.T_base_right)):
            np.testing.assert_allclose(model.camera_pose(q), T, atol=1e-6)
            assert model.within_limits(q, 0.05)
        baseline = v.T_base_right[:3, 3] - v.T_base_left[:3, 3]
        np.testing.assert_allclose(baseline, 0.06 * v.T_base_camera[:3, 0], atol=1e-12)
        np.testing.assert_allclose(v.T_base_left[:3, :3], v.T_base_camera[:3, :3])
        assert v.sigma_min >= 0.02 and v.joint_margin >= 0.05
    assert "viewpoint" in "\n".join(ring_plan.describe())


def test_the_baseline_stays_level_where_a_level_roll_is_reachable(model, ring_plan):
    # Quarter-turned pairs lost the walls facing them (bench/results/fused_footprint.md); on
    # this ring every viewpoint is reachable with the camera level (roll 0 or 180 deg).
    assert ring_plan.views and all(v.roll_deg in LEVEL_ROLLS_DEG for v in ring_plan.views)
    for v in ring_plan.views:
        assert abs(v.T_base_camera[2, 0]) < 1e-9  # camera x, the baseline, is horizontal


def test_views_out_of_reach_are_dropped_with_a_reason(model):
    plan = plan_scan(model, mock_start_configuration(model), (-1.5, 0.0, 0.0),
                     views="ring:4", radius=0.3, elevation_deg=45.0, baseline=0.06)
    assert plan.views == [] and len(plan.dropped) == 4
    assert all(d.check in ("IK", "workspace") and d.reason for d in plan.dropped)
    text = "\n".join(plan.describe())
    assert "0 of 4 viewpoints kept" in text and "dropped viewpoint 3" in text


def test_workspace_box_drops_views(model):
    low = Workspace((-1.0, -1.0, 0.0), (1.0, 1.0, 0.35))  # the cameras fly at about 0.4 m
    from armstereo.capture.scan_plan import ScanSettings

    plan = plan_scan(model, mock_start_configuration(model), TARGET, views="ring:3",
                     settings=ScanSettings(workspace=low))
    assert plan.views == [] and {d.check for d in plan.dropped} == {"workspace"}
    assert "leaves" in plan.dropped[0].reason


def test_bad_options(model):
    q = mock_start_configuration(model)
    for kwargs in ({"radius": 0.0}, {"elevation_deg": 95.0}, {"baseline": 0.0},
                   {"baseline": 0.5, "radius": 0.4}):
        with pytest.raises(ConfigError):
            plan_scan(model, q, TARGET, **kwargs)
    with pytest.raises(ConfigError, match="--target"):
        plan_scan(model, q, (1.0, 2.0))


def test_tour_visits_a_ring_in_order():
    # Joints that turn with the viewpoint: a shuffled ring comes back in ring order, starting
    # next to the start joints (the shortest tour).
    n = 8
    angles = np.linspace(0, 2 * np.pi, n, endpoint=False)
    q = [np.array([a, 0, 0, 0, 0, 0]) for a in angles]
    shuffle = [3, 6, 0, 5, 2, 7, 1, 4]
    order, cost = order_tour(np.array([angles[0] - 0.3, 0, 0, 0, 0, 0]),
                             [q[i] for i in shuffle], [q[i] for i in shuffle])
    visited = [shuffle[i] for i in order]
    assert visited == list(range(n))
    # joints do not wrap: out from the start, along the ring, and all the way back
    assert cost == pytest.approx(0.3 + angles[-1] + (angles[-1] + 0.3))


def test_tour_of_nothing():
    assert order_tour(np.zeros(6), [], []) == ([], 0.0)
