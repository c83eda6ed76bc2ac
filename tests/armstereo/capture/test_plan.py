"""Pre-flight properties of ``plan_capture`` (Hypothesis): a plan that passes never takes a
joint within the margin of its limit, the Jacobian's smallest singular value under the
threshold, or the flange or camera out of the workspace box at any sample of its path, and
refuses speeds over the caps and baselines along the optical axis.

The oracle walks the straight path itself the way the plan's contract states it (IK every
``path_step`` metres with warm starts, module doc of armstereo/capture/plan.py) and measures
every quantity; the thresholds are then drawn around the measured extremes, so that every
example sits close to a decision and a check that looks at the wrong thing, with the wrong
sign or not at all is caught.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from functools import cache

import cv2
import numpy as np
import pytest
from hypothesis import assume, example, given
from hypothesis import settings as hyp_settings
from hypothesis import strategies as st

from armstereo.capture import CaptureSettings, Workspace, plan_capture
from armstereo.capture.plan import (
    MAX_BASELINE_M,
    MAX_PAIRS,
    MAX_SAMPLE_JUMP_RAD,
    MIN_ANGLE_TO_OPTICAL_AXIS_DEG,
    check_motion,
    check_path,
    check_speed,
    parse_direction,
    validate_settings,
)
from armstereo.devices import (
    MAX_JOINT_ACCELERATION,
    MAX_JOINT_SPEED,
    MAX_LINEAR_ACCELERATION,
    MAX_LINEAR_SPEED,
    MotionLimits,
    trapezoid_duration,
)
from armstereo.errors import ConfigError, IKError, PreflightError
from armstereo.robot.arm_model import ArmModel
from drivers.mock.start_poses import table_start
from tests.support.properties import examples

TIE = 1e-9  # thresholds this close to a measured value are a coin toss, not a test


@cache
def arm(name: str = "ur5e") -> ArmModel:
    return ArmModel.load(name, mount="default_wrist_camera")


@dataclass
class Walk:
    """What the path really does, sample by sample (``None`` joints: IK failed there)."""

    qs: np.ndarray | None
    flanges: np.ndarray  # (n, 3) base frame, m
    cameras: np.ndarray
    view_qs: list[np.ndarray]

    @property
    def reachable(self) -> bool:
        return self.qs is not None


def walk(model: ArmModel, q0: np.ndarray, s: CaptureSettings) -> Walk:
    """Sample the straight camera path every ``path_step`` (views on samples) with warm IK."""
    T0 = model.flange_pose(q0)
    T_fc = model.mount.T_flange_camera
    step = (T0 @ T_fc)[:3, :3] @ (s.baseline * s.direction)
    per_pair = math.ceil(s.baseline / s.path_step)
    poses, qs, q = [], [], q0
    for i in range(per_pair * s.pairs + 1):
        T = T0.copy()
        T[:3, 3] += (i / per_pair) * step
        poses.append(T)
        try:
            q = model.ik(T, q)
        except IKError:
            qs = None
            break
        qs.append(q)
    flanges = np.array([T[:3, 3] for T in poses])
    cameras = np.array([(T @ T_fc)[:3, 3] for T in poses])
    if qs is None:
        return Walk(None, flanges, cameras, [])
    qs = np.array(qs)
    return Walk(qs, flanges, cameras, [qs[k * per_pair] for k in range(s.pairs + 1)])


def margins(model: ArmModel, qs: np.ndarray) -> np.ndarray:
    """Distance of each sample's nearest joint to its limit (rad)."""
    return np.minimum(qs - model.lower, model.upper - qs).min(axis=1)


def check(plan, name: str):
    return next(c for c in plan.checks if c.name == name)


def unit(v) -> np.ndarray:
    v = np.asarray(v, dtype=float)
    return v / np.linalg.norm(v)


# --- strategies -----------------------------------------------------------------------------

fractions = st.floats(0.0, 1.0)


@st.composite
def capture_cases(draw, sideways: bool = True):
    """A random start pose near the mock table pose, direction, baseline and pair count."""
    model = arm(draw(st.sampled_from(["ur5e", "ur5e", "ur10e"])))
    q0 = table_start(model) + np.array(draw(st.lists(st.floats(-0.6, 0.6), min_size=6,
                                                     max_size=6)))
    assume(model.within_limits(q0))
    v = np.array(draw(st.lists(st.floats(-1, 1), min_size=3, max_size=3)))
    assume(np.linalg.norm(v) > 0.1)
    v = unit(v)
    if sideways:  # keep the direction check out of the way of the others
        assume(math.degrees(math.acos(min(1.0, abs(v[2])))) >= MIN_ANGLE_TO_OPTICAL_AXIS_DEG)
    s = CaptureSettings(baseline=draw(st.floats(0.004, 0.25)), direction=v,
                        direction_label="random", pairs=draw(st.integers(1, 3)))
    return model, q0, s


def between(lo: float, hi: float, f: float) -> float:
    return lo + f * (hi - lo)


# --- the safety properties ------------------------------------------------------------------

@hyp_settings(max_examples=examples(30))
@given(capture_cases(), fractions)
def test_a_plan_that_passes_keeps_every_joint_outside_the_margin(case, f):
    model, q0, s = case
    path = walk(model, q0, s)
    assume(path.reachable)
    m = margins(model, path.qs)
    # margins drawn between just under the path's tightest sample and just over the start's
    margin = between(0.9 * m.min(), 1.1 * m[0], f)
    assume(abs(margin - m.min()) > TIE and abs(margin - m[0]) > TIE)
    plan = plan_capture(model, q0, replace(s, joint_margin=margin))
    if plan.ok:
        assert m.min() >= margin, plan.describe()
    # and it refuses only for a reason: both checks agree with what the path does
    assert check(plan, "joint limits").ok == (m.min() >= margin)
    assert check(plan, "start pose").ok == (m[0] >= margin)


@hyp_settings(max_examples=examples(30))
@given(capture_cases(), fractions)
def test_a_plan_that_passes_stays_clear_of_singularities(case, f):
    model, q0, s = case
    path = walk(model, q0, s)
    assume(path.reachable)
    sigma = np.array([model.sigma_min(q) for q in path.qs])
    threshold = between(0.8 * sigma.min(), 1.2 * sigma.max(), f)
    assume(abs(threshold - sigma.min()) > TIE)
    plan = plan_capture(model, q0, replace(s, min_sigma=threshold))
    if plan.ok:
        assert sigma.min() >= threshold, plan.describe()
    assert check(plan, "singularity").ok == (sigma.min() >= threshold)


@st.composite
def slacks(draw):
    """Per-face slack of a box around the path (m): negative slack cuts into it."""
    return np.array(draw(st.lists(st.floats(-0.08, 0.03), min_size=6, max_size=6)))


@hyp_settings(max_examples=examples(30))
@given(capture_cases(), slacks())
def test_a_plan_that_passes_keeps_flange_and_camera_inside_the_workspace(case, slack):
    model, q0, s = case
    path = walk(model, q0, s)
    points = np.vstack([path.flanges, path.cameras])
    lo = points.min(axis=0) - slack[:3]
    hi = points.max(axis=0) + slack[3:]
    assume(np.all(hi - lo > 0.01))
    box = Workspace(tuple(lo), tuple(hi))
    # the plan computes the same points from the same numbers, so a point on a face is no tie
    inside = bool(np.all(points >= lo) and np.all(points <= hi))
    plan = plan_capture(model, q0, replace(s, workspace=box))
    if plan.ok:
        assert inside, plan.describe()
    if path.reachable:
        assert check(plan, "workspace").ok == inside
        if not inside:  # the refusal names a point that really is outside
            named = np.array([float(v) for v in check(plan, "workspace").detail.split("(")[1]
                              .split(")")[0].split(",")])
            outside = points[~(np.all(points >= lo, axis=1) & np.all(points <= hi, axis=1))]
            assert np.abs(outside - named).max(axis=1).min() <= 0.0005


@pytest.mark.parametrize("direction", [(1, 0, 0), (0, -1, 0), (1, 1, 0.5)])
def test_a_floor_between_camera_and_flange_is_refused(direction):
    """Looking down, the camera hangs below the flange: a box floor between the two must
    refuse the plan (the camera would leave the box into the table), one just below the
    camera must not."""
    model = arm()
    q0 = table_start(model)
    s = CaptureSettings(baseline=0.05, direction=unit(direction), pairs=2)
    path = walk(model, q0, s)
    assert path.cameras[:, 2].max() < path.flanges[:, 2].min()
    for floor, ok in ((path.cameras[:, 2].max() + 0.005, False),
                      (path.cameras[:, 2].min() - 0.005, True)):
        box = Workspace((-2.0, -2.0, floor), (2.0, 2.0, 2.0))
        assert check(plan_capture(model, q0, replace(s, workspace=box)), "workspace").ok == ok


@hyp_settings(max_examples=examples(25))
@given(capture_cases(), fractions, st.floats(0.002, 0.15))
def test_a_plan_that_passes_moves_no_joint_further_than_allowed(case, f, path_step):
    """Also with coarse path sampling (path_step is a setting), where a path may have only
    two samples and large joint changes between them."""
    model, q0, s = case
    s = replace(s, path_step=path_step)
    path = walk(model, q0, s)
    assume(path.reachable)
    jumps = np.abs(np.diff(path.qs, axis=0)).max()
    travel = max(np.abs(b - a).max()
                 for a, b in zip(path.view_qs[:-1], path.view_qs[1:], strict=True))
    limit = between(0.8 * travel, 1.2 * travel, f)
    assume(abs(limit - travel) > TIE)
    plan = plan_capture(model, q0, replace(s, max_joint_travel=limit))
    if plan.ok:
        assert travel <= limit and jumps <= MAX_SAMPLE_JUMP_RAD
    assert check(plan, "joint travel").ok == (travel <= limit)
    assert f"{len(path.qs)} samples every {path_step * 1000:.0f} mm" in \
        check(plan, "IK along the path").detail
    assert check(plan, "path continuity").ok == (jumps <= MAX_SAMPLE_JUMP_RAD)
    for q_plan, q_path in zip(plan.q_views, path.view_qs, strict=True):
        np.testing.assert_allclose(q_plan, q_path, atol=1e-12)


@hyp_settings(max_examples=examples(30))
@given(capture_cases(sideways=False))
def test_a_plan_that_passes_moves_sideways_to_the_optical_axis(case):
    model, q0, s = case
    angle = math.degrees(math.acos(min(1.0, abs(float(s.direction[2])))))
    assume(abs(angle - MIN_ANGLE_TO_OPTICAL_AXIS_DEG) > 1e-6)
    plan = plan_capture(model, q0, s)
    assert check(plan, "baseline direction").ok == (angle >= MIN_ANGLE_TO_OPTICAL_AXIS_DEG)


@pytest.mark.parametrize("direction", [(1.0, 1.0, 0.0), (0.5, 0.0, 0.0), (np.nan, 0.0, 1.0),
                                       (1.0, 0.0), (1.0, 0.0, 0.0, 0.0), (0.0, 0.0, 0.0)])
def test_a_direction_that_is_not_a_unit_vector_is_refused(direction):
    """The step is baseline x direction: a longer vector would move the arm farther than asked."""
    model = arm()
    s = CaptureSettings(baseline=0.02, direction=np.array(direction))
    with pytest.raises(ConfigError, match="unit vector"):
        plan_capture(model, table_start(model), s)


def test_a_direction_along_the_axis_to_within_rounding_is_refused_not_a_crash():
    """|z| may exceed 1 by rounding (a unit vector to UNIT_TOL): still a refused plan."""
    model = arm()
    s = CaptureSettings(baseline=0.02, direction=np.array([0.0, 0.0, -(1 + 5e-10)]))
    plan = plan_capture(model, table_start(model), s)
    assert not check(plan, "baseline direction").ok and not plan.ok


@hyp_settings(max_examples=examples(6))
@given(capture_cases())
def test_unreachable_paths_are_refused(case):
    model, q0, s = case
    s = replace(s, baseline=MAX_BASELINE_M, pairs=6)  # 3 m: more than any UR's reach across
    path = walk(model, q0, s)
    plan = plan_capture(model, q0, s)
    assert not path.reachable
    assert not plan.ok and not check(plan, "IK along the path").ok
    named = [float(v) for v in check(plan, "IK along the path").detail.split("(")[1]
             .split(")")[0].split(",")]
    np.testing.assert_allclose(named, path.flanges[-1], atol=0.0005)  # the first failing one
    with pytest.raises(PreflightError, match="nothing moved"):
        plan.require_ok()
    assert all(q.shape == (6,) for q in plan.q_views)  # one joint vector per view ...
    assert np.isnan(plan.q_views[-1]).all()  # ... NaN where the path cannot go


@hyp_settings(max_examples=examples(40))
@example(baseline=0.1, pairs=MAX_PAIRS, settle=0.0)  # every limit itself is allowed
@example(baseline=MAX_BASELINE_M, pairs=1, settle=0.0)
@example(baseline=0.0, pairs=1, settle=0.5)
@example(baseline=0.1, pairs=0, settle=0.5)
@example(baseline=0.1, pairs=MAX_PAIRS + 1, settle=0.5)
@example(baseline=0.1, pairs=1, settle=-0.01)
@given(baseline=st.one_of(st.floats(-1.0, 1.0), st.sampled_from([0.0, MAX_BASELINE_M])),
       pairs=st.integers(-2, MAX_PAIRS + 2), settle=st.floats(-1.0, 2.0))
def test_settings_out_of_range_are_refused_before_planning(baseline, pairs, settle):
    s = CaptureSettings(baseline=baseline, direction=unit([1, 0, 0]), pairs=pairs,
                        settle_s=settle)
    valid = 0 < baseline <= MAX_BASELINE_M and 1 <= pairs <= MAX_PAIRS and settle >= 0
    if valid:
        validate_settings(s)
    else:
        with pytest.raises(ConfigError):
            validate_settings(s)
        with pytest.raises(ConfigError):
            plan_capture(arm(), table_start(arm()), s)


@pytest.mark.parametrize(("robot", "published_reach_m"), [("ur5e", 0.85), ("ur10e", 1.30),
                                                         ("ur3e", 0.50)])
def test_the_default_workspace_is_the_arms_reach_above_the_base_plane(robot, published_reach_m):
    """Workspace.around: the stretched arm's flange distance (q = 0) in x and y, from z_min up
    to it; that distance is within 10 % of the published reach (UR data sheets)."""
    model = arm(robot)
    reach = float(np.linalg.norm(model.flange_pose(np.zeros(6))[:3, 3]))
    box = Workspace.around(model, z_min=0.05)
    np.testing.assert_allclose(box.hi, (reach, reach, reach), rtol=1e-12)
    np.testing.assert_allclose(box.lo, (-reach, -reach, 0.05), rtol=1e-12)
    default = Workspace.around(model)  # keeps the camera above the base plane (the table)
    assert not default.contains(np.array([0.3, 0.3, -0.001]))
    assert default.contains(np.array([0.3, 0.3, 0.3]))
    assert abs(reach - published_reach_m) < 0.1 * published_reach_m


# --- speed and acceleration caps ------------------------------------------------------------

CAPS = {"linear_speed": MAX_LINEAR_SPEED, "linear_acceleration": MAX_LINEAR_ACCELERATION,
        "joint_speed": MAX_JOINT_SPEED, "joint_acceleration": MAX_JOINT_ACCELERATION}


@hyp_settings(max_examples=examples(40))
@example(field="linear_speed", factor=0.0, exact=False)  # zero: no motion profile exists
@example(field="linear_acceleration", factor=0.0, exact=False)
@example(field="linear_acceleration", factor=-0.5, exact=False)
@given(field=st.sampled_from(sorted(CAPS)), factor=st.floats(-0.5, 2.5, allow_nan=False),
       exact=st.booleans())
def test_speeds_and_accelerations_over_the_caps_are_refused(field, factor, exact):
    """Every motion limit must lie in (0, cap]: zero or less is malformed (ConfigError before
    any plan: no motion profile exists), over the cap the plan's "speed caps" check refuses."""
    cap = CAPS[field]
    value = cap if exact else factor * cap  # the cap itself is allowed
    model = arm()
    s = CaptureSettings(baseline=0.02, direction=unit([1, 0, 0]),
                        limits=replace(MotionLimits(), **{field: value}))
    if value <= 0:
        with pytest.raises(ConfigError, match="must be > 0"):
            plan_capture(model, table_start(model), s)
        return
    plan = plan_capture(model, table_start(model), s)
    allowed = value <= cap
    assert check(plan, "speed caps").ok == allowed
    assert plan.ok == allowed
    assert plan.describe()  # a refused plan still shows every check
    assert math.isfinite(plan.duration_s)
    if not allowed:
        with pytest.raises(PreflightError, match="speed caps"):
            plan.require_ok()


def test_the_default_limits_are_under_the_caps():
    lim = MotionLimits()
    for field, cap in CAPS.items():
        assert 0 < getattr(lim, field) <= cap


# --- what the plan says it will do ----------------------------------------------------------

@hyp_settings(max_examples=examples(15))
@given(capture_cases(), st.floats(0.0, 1.0))
def test_views_and_duration_are_what_the_path_and_profile_give(case, settle):
    model, q0, s = case
    s = replace(s, settle_s=settle)
    plan = plan_capture(model, q0, s)
    T0 = model.flange_pose(q0)
    step = model.camera_pose(q0)[:3, :3] @ (s.baseline * s.direction)
    assert len(plan.T_base_flange) == len(plan.camera_positions) == s.pairs + 1
    for k, (T, c) in enumerate(zip(plan.T_base_flange, plan.camera_positions, strict=True)):
        np.testing.assert_allclose(T[:3, :3], T0[:3, :3], atol=0)
        np.testing.assert_allclose(T[:3, 3], T0[:3, 3] + k * step, atol=1e-12)
        np.testing.assert_allclose(c, (T @ model.mount.T_flange_camera)[:3, 3], atol=1e-12)
    lim = s.limits
    move = trapezoid_duration(s.baseline, lim.linear_speed, lim.linear_acceleration)
    back = trapezoid_duration(s.baseline * s.pairs, lim.linear_speed, lim.linear_acceleration)
    expected = s.pairs * move + back + (s.pairs + 1) * settle
    assert plan.duration_s == pytest.approx(expected, rel=1e-12)


# --- the limits themselves, the building blocks the tours share -------------------------------

def test_the_margin_and_sigma_limits_themselves_are_allowed():
    """"needs >= limit": a path whose tightest sample sits exactly on the limit passes, one a
    bit past it does not (the checks are public: the scan tours call them too)."""
    model = arm()
    q = table_start(model)
    T = model.flange_pose(q)
    box = Workspace.around(model)
    margin = float(np.minimum(q - model.lower, model.upper - q).min())
    sigma = float(model.sigma_min(q))
    s = CaptureSettings(baseline=0.02, direction=unit([1, 0, 0]), joint_margin=margin,
                        min_sigma=sigma)
    on = {c.name: c.ok for c in check_path(model, [(T, q, "")], s, box)}
    assert on["joint limits"] and on["singularity"]
    past = replace(s, joint_margin=float(np.nextafter(margin, np.inf)),
                   min_sigma=float(np.nextafter(sigma, np.inf)))
    off = {c.name: c.ok for c in check_path(model, [(T, q, "")], past, box)}
    assert not off["joint limits"] and not off["singularity"]
    # a one-sample path (one view, no move) has no jump between samples
    assert on["path continuity"] and on["IK along the path"]


def test_the_joint_travel_limit_itself_is_allowed():
    model = arm()
    q0 = table_start(model)
    s = CaptureSettings(baseline=0.05, direction=unit([1, 0, 0]), pairs=2)
    views = walk(model, q0, s).view_qs
    travel = max(float(np.abs(b - a).max()) for a, b in zip(views[:-1], views[1:], strict=True))
    assert check(plan_capture(model, q0, replace(s, max_joint_travel=travel)), "joint travel").ok
    past = replace(s, max_joint_travel=float(np.nextafter(travel, 0)))
    assert not check(plan_capture(model, q0, past), "joint travel").ok


@pytest.mark.parametrize("field", sorted(CAPS))
@pytest.mark.parametrize("value", [0.0, -0.1])
def test_the_speed_caps_check_refuses_zero_and_negative_limits(field, value):
    """The tours call check_speed on limits that did not go through validate_settings."""
    assert not check_speed(replace(MotionLimits(), **{field: value})).ok
    assert check_speed(MotionLimits()).ok


def test_a_pure_rotation_and_a_forward_move_are_not_stereo():
    """check_motion refuses a pair whose camera only turns (no baseline) and one whose epipole
    lies in the image (moving along the optical axis), each on its own."""
    model = arm()
    T_fc = model.mount.T_flange_camera
    T0 = model.flange_pose(table_start(model))
    cam0 = T0 @ T_fc
    turn = np.eye(4)
    turn[:3, :3] = cv2.Rodrigues(np.array([0.0, 0.2, 0.0]))[0]
    turned = cam0 @ turn @ np.linalg.inv(T_fc)  # the camera turns about its own centre
    ahead = cam0.copy()
    ahead[:3, 3] += cam0[:3, 2] * 0.05  # 5 cm along the optical axis
    forward = ahead @ np.linalg.inv(T_fc)
    sideways = cam0.copy()
    sideways[:3, 3] += cam0[:3, 0] * 0.05
    assert not check_motion(model, [T0, turned]).ok
    assert not check_motion(model, [T0, forward]).ok
    assert check_motion(model, [T0, sideways @ np.linalg.inv(T_fc)]).ok


@pytest.mark.parametrize("text", ["1,2", "1,2,3,4", "nan,0,0", "0,0,0", "1e-10,0,0", "sideways",
                                  ""])
def test_a_malformed_direction_is_refused(text):
    with pytest.raises(ConfigError, match="--direction"):
        parse_direction(text)


def test_directions_are_named_or_normalised():
    d, label = parse_direction(" -Y ")
    assert label == "-y" and np.array_equal(d, [0.0, -1.0, 0.0])
    for text in ("3,4,0", "0.6,0.8,0", "0.3,0.4,0"):
        d, label = parse_direction(text)
        assert label == text
        np.testing.assert_allclose(d, [0.6, 0.8, 0.0], rtol=0, atol=1e-15)
    d, _ = parse_direction("1e-9,0,0")  # the shortest vector accepted: only its direction counts
    assert np.array_equal(d, [1.0, 0.0, 0.0])


def test_the_steps_shoot_view_0_then_one_pair_per_move_and_return():
    model = arm()
    s = CaptureSettings(baseline=0.02, direction=unit([1, 0, 0]), direction_label="x", pairs=3)
    plan = plan_capture(model, table_start(model), s)
    steps = plan.steps()
    assert [st_.view for st_ in steps] == [0, 1, 2, 3, None]
    assert [st_.move for st_ in steps] == ["none", "linear", "linear", "linear", "linear"]
    pairs = [st_.pair for st_ in steps if st_.pair is not None]
    assert [(p.pair, p.left_view, p.right_view) for p in pairs] == [(0, 0, 1), (1, 1, 2), (2, 2, 3)]
    assert all(type(v) is int for p in pairs for v in (p.pair, p.left_view, p.right_view))
    assert all(p.commanded_m == 0.02 and p.direction == "x" for p in pairs)
    for k in (1, 2, 3):
        assert np.array_equal(steps[k].target, plan.T_base_flange[k])
    assert np.array_equal(steps[-1].target, plan.T_base_flange[0])  # back to the start


def test_the_continuity_limit_itself_is_allowed():
    """A jump of exactly MAX_SAMPLE_JUMP_RAD between two samples passes, a bit more does not."""
    model = arm()
    q = table_start(model).copy()
    q[0] = 0.0  # so that the step below is exactly the limit in floating point
    box = Workspace.around(model)
    s = CaptureSettings(baseline=0.02, direction=unit([1, 0, 0]))
    for jump, ok in ((MAX_SAMPLE_JUMP_RAD, True), (np.nextafter(MAX_SAMPLE_JUMP_RAD, 1), False)):
        q2 = q.copy()
        q2[0] = jump
        assert q2[0] - q[0] == jump
        samples = [(model.flange_pose(x), x, "") for x in (q, q2)]
        assert {c.name: c.ok for c in check_path(model, samples, s, box)}["path continuity"] == ok


def test_a_single_point_outside_the_workspace_is_named():
    """Only the path's last camera position pokes out of the box: refused, and named."""
    model = arm()
    q0 = table_start(model)
    s = CaptureSettings(baseline=0.05, direction=unit([1, 0, 0]), pairs=2)
    path = walk(model, q0, s)
    points = np.vstack([path.flanges, path.cameras])
    axis = int(np.argmax(np.ptp(points, axis=0)))  # the axis the path runs along most
    order = np.sort(points[:, axis])
    lo, hi = points.min(axis=0) - 0.01, points.max(axis=0) + 0.01
    hi[axis] = (order[-1] + order[-2]) / 2  # between the farthest point and the next one
    plan = plan_capture(model, q0, replace(s, workspace=Workspace(tuple(lo), tuple(hi))))
    refused = check(plan, "workspace")
    assert not refused.ok
    named = np.array([float(v) for v in refused.detail.split("(")[1].split(")")[0].split(",")])
    farthest = points[np.argmax(points[:, axis])]
    assert np.abs(named - farthest).max() <= 0.0005

