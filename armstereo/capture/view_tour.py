"""A tour of joint moves through planned views, checked before anything moves.

Views that do not lie on one straight line (a calibration's tilted, rolled views around a
board) are visited by joint moves (UR moveJ): all joints start and stop together and the joints
move on a straight line in joint space. Each move, the return to the start included, gets
capture's pre-flight checks (:mod:`armstereo.capture.plan`) on its whole path, sampled every
``joint_step`` rad of the leading joint: the speed caps, the start pose, joint limits with a
margin (the path is a segment in joint space, so its ends bound it), the smallest Jacobian
singular value, the joint travel per move, and the workspace box for flange and camera. The
move's speed is set so that neither the flange nor the camera moves faster than the linear
speed and acceleration caps (a joint move's tool speed is the joints' speed times the
lever arm), and never faster than the joint caps. Nothing here moves anything; all poses are
in the controller's ``base`` frame.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from armstereo import validate
from armstereo.capture.plan import (
    MAX_SETTLE_S,
    Check,
    Workspace,
    _check_speed,  # the very checks capture runs, shared so they cannot drift apart
    _check_start,
)
from armstereo.devices import MotionLimits, trapezoid_duration
from armstereo.errors import PreflightError
from armstereo.kinematics import ArmModel

DEFAULT_JOINT_STEP_RAD = 0.02  # path samples: 0.02 rad of the leading joint ~ 1 cm at the flange
# Calibration views roll the camera by up to +-60 deg about its axis, so consecutive views may
# differ by about 2 rad on the last wrist joint; more than this is a branch flip.
DEFAULT_MAX_JOINT_TRAVEL_RAD = 2.5
SAME_JOINTS_RAD = 1e-9  # a move shorter than this is not made


@dataclass(frozen=True)
class TourSettings:
    """How the tour moves. ``limits``: joint caps (rad/s, rad/s^2) and the linear caps the
    flange and camera must stay under (m/s, m/s^2); lengths m, angles rad, times s."""

    settle_s: float = 0.5
    limits: MotionLimits = field(default_factory=MotionLimits)
    joint_margin: float = 0.05
    min_sigma: float = 0.02
    max_joint_travel: float = DEFAULT_MAX_JOINT_TRAVEL_RAD
    joint_step: float = DEFAULT_JOINT_STEP_RAD
    workspace: Workspace | None = None  # None: Workspace.around(model)


@dataclass(frozen=True)
class JointMove:
    """One joint move of the tour: from view ``src`` to view ``dst`` (-1 = back to the start),
    at ``speed`` rad/s and ``acceleration`` rad/s^2 of the leading joint; ``peak_tool_speed``
    m/s is the fastest the flange or camera gets; ``lever_m`` their largest displacement per
    rad of the leading joint."""

    src: int
    dst: int
    q_from: np.ndarray
    q_to: np.ndarray
    travel_rad: float
    speed: float
    acceleration: float
    duration_s: float
    lever_m: float
    peak_tool_speed: float


@dataclass
class TourPlan:
    """The checked tour: views (joints, camera poses), the moves between them and the checks."""

    settings: TourSettings
    q_start: np.ndarray
    q_views: list[np.ndarray]
    T_base_camera: list[np.ndarray]
    moves: list[JointMove]
    checks: list[Check]
    duration_s: float

    @property
    def ok(self) -> bool:
        return all(c.ok for c in self.checks)

    def require_ok(self) -> None:
        """Raise PreflightError naming the first failed check (nothing has moved)."""
        for c in self.checks:
            if not c.ok:
                raise PreflightError(f"pre-flight check '{c.name}' failed: {c.detail}; "
                                     "nothing moved")

    def move_to(self, view: int) -> JointMove | None:
        """The move that ends at ``view`` (None for a view reached without moving)."""
        return next((m for m in self.moves if m.dst == view), None)

    @property
    def move_home(self) -> JointMove | None:
        return self.move_to(-1)

    def describe(self) -> list[str]:
        """Human-readable lines: the moves and every check."""
        s, lim = self.settings, self.settings.limits
        lines = [f"tour: {len(self.q_views)} views by joint moves, then back to the start; "
                 f"estimated {self.duration_s:.1f} s",
                 f"  caps: joints {lim.joint_speed:.2f} rad/s, {lim.joint_acceleration:.2f} "
                 f"rad/s^2; flange and camera {lim.linear_speed:.3f} m/s, "
                 f"{lim.linear_acceleration:.2f} m/s^2; settle {s.settle_s:.2f} s per view"]
        for m in self.moves:
            dst = "start" if m.dst < 0 else f"view {m.dst}"
            lines.append(f"    move {m.src} -> {dst}: largest joint {m.travel_rad:.3f} rad at "
                         f"{m.speed:.3f} rad/s (tool at most {m.peak_tool_speed:.3f} m/s), "
                         f"{m.duration_s:.1f} s")
        lines.append("  pre-flight checks:")
        lines += [f"    [{'ok' if c.ok else 'FAIL'}] {c.name}: {c.detail}" for c in self.checks]
        return lines


def plan_tour(model: ArmModel, q_start: np.ndarray, q_views: list[np.ndarray],
              settings: TourSettings = TourSettings()) -> TourPlan:
    """Check a tour from ``q_start`` through ``q_views`` (rad, in order) and back.

    Never raises for a failed check (so --dry-run can show them all); call
    ``plan.require_ok()`` before moving. Raises ConfigError for malformed settings.
    """
    _validate(settings, len(q_views))
    q_start = np.asarray(q_start, dtype=float).reshape(6)
    views = [np.asarray(q, dtype=float).reshape(6) for q in q_views]
    stops = [q_start, *views, q_start]
    labels = [-1, *range(len(views)), -1]
    box = settings.workspace or Workspace.around(model)
    moves, samples = [], []
    for k in range(len(stops) - 1):
        a, b = stops[k], stops[k + 1]
        if float(np.abs(b - a).max()) < SAME_JOINTS_RAD:
            continue
        path = _joint_path(a, b, settings.joint_step)
        samples.append(path)
        moves.append(_timed_move(model, labels[k], labels[k + 1], path, settings))
    checks = [_check_speed(settings.limits), _check_start(model, q_start, settings),
              _check_limits(model, views, settings)]
    checks += _check_paths(model, samples, settings, box)
    checks.append(_check_travel(moves, settings))
    checks.append(_check_tool_speed(moves, settings.limits))
    duration = sum(m.duration_s for m in moves) + len(views) * settings.settle_s
    cams = [model.camera_pose(q) for q in views]
    return TourPlan(settings, q_start, views, cams, moves, checks, duration)


def _validate(s: TourSettings, n_views: int) -> None:
    validate.non_negative(s.settle_s, "--settle", "s", cap=MAX_SETTLE_S)
    lim = s.limits
    validate.positive(lim.linear_speed, "--speed", "m/s")
    validate.positive(lim.linear_acceleration, "--acceleration", "m/s^2")
    validate.positive(lim.joint_speed, "joint speed", "rad/s")
    validate.positive(lim.joint_acceleration, "joint acceleration", "rad/s^2")
    validate.positive(s.joint_step, "joint step", "rad", cap=0.5)
    validate.positive(s.max_joint_travel, "max joint travel", "rad", cap=2 * math.pi)
    validate.whole(n_views, "number of views", 1, 1000)


def _joint_path(a: np.ndarray, b: np.ndarray, step: float) -> np.ndarray:
    """(n+1, 6) joints on the segment from a to b, every ``step`` rad of the leading joint."""
    n = max(1, math.ceil(float(np.abs(b - a).max()) / step))
    s = np.arange(n + 1)[:, None] / n
    return a + s * (b - a)


def _timed_move(model: ArmModel, src: int, dst: int, path: np.ndarray,
                s: TourSettings) -> JointMove:
    """The move along ``path`` at the fastest leading-joint speed that keeps flange and camera
    under the linear caps (and the joints under theirs)."""
    lim = s.limits
    travel = float(np.abs(path[-1] - path[0]).max())
    points = [np.stack([T[:3, 3], (T @ model.mount.T_flange_camera)[:3, 3]])
              for T in (model.flange_pose(q) for q in path)]
    step = travel / (len(path) - 1)
    lever = max(float(np.linalg.norm(p1 - p0, axis=1).max()) / step
                for p0, p1 in zip(points[:-1], points[1:], strict=True))
    speed = min(lim.joint_speed, lim.linear_speed / lever) if lever > 0 else lim.joint_speed
    accel = (min(lim.joint_acceleration, lim.linear_acceleration / lever) if lever > 0
             else lim.joint_acceleration)
    duration = trapezoid_duration(travel, speed, accel)
    peak = min(speed, math.sqrt(travel * accel))  # a short move never reaches cruise speed
    return JointMove(src, dst, path[0], path[-1], travel, speed, accel, duration, lever,
                     peak * lever)


def _check_limits(model: ArmModel, views: list[np.ndarray], s: TourSettings) -> Check:
    margins = [float(np.minimum(q - model.lower, model.upper - q).min()) for q in views]
    worst = min(margins)
    return Check("joint limits", worst >= s.joint_margin,
                 f"smallest margin {worst:.3f} rad at the views, hence along every joint move "
                 f"(needs >= {s.joint_margin:.3f})")


def _check_paths(model: ArmModel, paths: list[np.ndarray], s: TourSettings,
                 box: Workspace) -> list[Check]:
    qs = np.concatenate(paths) if paths else np.zeros((0, 6))
    if not len(qs):
        return [Check("singularity", True, "no move"), Check("workspace", True, "no move")]
    sigma = min(model.sigma_min(q) for q in qs)
    outside = None
    for q in qs:
        T = model.flange_pose(q)
        for p in (T[:3, 3], (T @ model.mount.T_flange_camera)[:3, 3]):
            if not box.contains(p):
                outside = p
                break
        if outside is not None:
            break
    detail = f"inside {box}"
    if outside is not None:
        detail = (f"point ({outside[0]:+.3f}, {outside[1]:+.3f}, {outside[2]:+.3f}) leaves "
                  f"{box}")
    return [Check("singularity", sigma >= s.min_sigma,
                  f"smallest Jacobian singular value {sigma:.4f} over {len(qs)} path samples "
                  f"(needs >= {s.min_sigma})"),
            Check("workspace", outside is None, detail)]


def _check_travel(moves: list[JointMove], s: TourSettings) -> Check:
    travel = max((m.travel_rad for m in moves), default=0.0)
    return Check("joint travel", travel <= s.max_joint_travel,
                 f"largest single-joint travel per move {travel:.3f} rad "
                 f"(needs <= {s.max_joint_travel})")


def _check_tool_speed(moves: list[JointMove], lim: MotionLimits) -> Check:
    peak = max((m.peak_tool_speed for m in moves), default=0.0)
    ok = peak <= lim.linear_speed * (1 + 1e-9)
    return Check("tool speed", ok, f"flange and camera at most {peak:.3f} m/s during the joint "
                 f"moves (cap {lim.linear_speed} m/s)")
