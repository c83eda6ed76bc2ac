"""Capture planning and pre-flight checks. Nothing here moves anything.

The camera moves by ``baseline`` metres along a camera-frame direction between consecutive
views, with its orientation unchanged; ``pairs`` pairs need ``pairs + 1`` views on one straight
line, and the arm returns along the same line at the end. Every check runs on the whole straight
path (IK solved every ``path_step`` metres with warm starts), not only at its end points.
All poses are in the controller's ``base`` frame.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from armstereo import validate
from armstereo.devices import (
    MAX_JOINT_ACCELERATION,
    MAX_JOINT_SPEED,
    MAX_LINEAR_ACCELERATION,
    MAX_LINEAR_SPEED,
    MotionLimits,
    trapezoid_duration,
)
from armstereo.epipolar.motion import classify_motion
from armstereo.errors import ConfigError, IKError, JointLimitError, PreflightError
from armstereo.robot.arm_model import ArmModel

NAMED_DIRECTIONS = {
    "x": (1.0, 0.0, 0.0), "-x": (-1.0, 0.0, 0.0),
    "y": (0.0, 1.0, 0.0), "-y": (0.0, -1.0, 0.0),
    "z": (0.0, 0.0, 1.0), "-z": (0.0, 0.0, -1.0),
}
MAX_BASELINE_M = 0.5
MAX_PAIRS = 50
MAX_SETTLE_S = 60.0  # longer than any arm needs to come to rest; larger values are typos
# Rectification (Fusiello) degenerates when the camera moves along its optical axis.
MIN_ANGLE_TO_OPTICAL_AXIS_DEG = 30.0
UNIT_TOL = 1e-9  # how far from length 1 a baseline direction may be (rounding only)
# A jump larger than this between IK samples 5 mm apart means a branch flip, not a smooth path.
MAX_SAMPLE_JUMP_RAD = 0.15


def parse_direction(text: str) -> tuple[np.ndarray, str]:
    """Camera-frame unit direction from ``x``, ``-y``, ... or ``"dx,dy,dz"``."""
    label = text.strip().lower()
    if label in NAMED_DIRECTIONS:
        return np.array(NAMED_DIRECTIONS[label]), label
    try:
        v = np.array([float(s) for s in label.split(",")])
    except ValueError:
        v = np.zeros(0)
    if v.shape != (3,) or not np.all(np.isfinite(v)) or np.linalg.norm(v) < 1e-9:
        raise ConfigError(f"--direction must be x, -x, y, -y, z, -z or 'dx,dy,dz', not {text!r}")
    return v / np.linalg.norm(v), label


@dataclass(frozen=True)
class Workspace:
    """Axis-aligned box in the base frame that the flange and camera must stay inside (m)."""

    lo: tuple[float, float, float]
    hi: tuple[float, float, float]

    @classmethod
    def parse(cls, text: str) -> Workspace:
        """From ``xmin,xmax,ymin,ymax,zmin,zmax``."""
        try:
            v = [float(s) for s in text.split(",")]
        except ValueError:
            v = []
        if len(v) != 6 or v[0] >= v[1] or v[2] >= v[3] or v[4] >= v[5]:
            raise ConfigError("--workspace must be xmin,xmax,ymin,ymax,zmin,zmax with min < max, "
                              f"not {text!r}")
        return cls((v[0], v[2], v[4]), (v[1], v[3], v[5]))

    @classmethod
    def around(cls, model: ArmModel, z_min: float = 0.05) -> Workspace:
        """Default box: the arm's reach in x and y, from ``z_min`` above the base plane up."""
        # The stretched arm at q = 0 is (to within a few mm) its reach.
        reach = float(np.linalg.norm(model.flange_pose(np.zeros(6))[:3, 3]))
        return cls((-reach, -reach, z_min), (reach, reach, reach))

    def contains(self, p: np.ndarray) -> bool:
        return bool(np.all(p >= np.array(self.lo)) and np.all(p <= np.array(self.hi)))

    def __str__(self) -> str:
        return (f"x [{self.lo[0]:.2f}, {self.hi[0]:.2f}] y [{self.lo[1]:.2f}, {self.hi[1]:.2f}] "
                f"z [{self.lo[2]:.2f}, {self.hi[2]:.2f}] m")


@dataclass(frozen=True)
class CaptureSettings:
    """What to capture and how carefully. Lengths m, angles rad, times s."""

    baseline: float
    direction: np.ndarray  # unit vector in the camera frame
    direction_label: str = "x"
    pairs: int = 1
    settle_s: float = 0.5
    limits: MotionLimits = field(default_factory=MotionLimits)
    joint_margin: float = 0.05
    min_sigma: float = 0.02
    max_joint_travel: float = 1.0  # per baseline move, any joint (catches branch flips)
    path_step: float = 0.005
    workspace: Workspace | None = None  # None: Workspace.around(model)


@dataclass(frozen=True)
class PairStep:
    """A stereo pair to record after a shot: views ``left_view`` and ``right_view``, the
    baseline commanded (m) along the camera-frame ``direction`` label, and the scan viewpoint
    the pair was shot from (None for a single-line capture)."""

    pair: int
    left_view: int
    right_view: int
    commanded_m: float
    direction: str
    viewpoint: int | None = None


@dataclass(frozen=True)
class Step:
    """One step of a checked capture: a move, then (optionally) a shot, then (optionally) a
    pair event. ``move`` is ``none``, ``linear`` (``target`` = T_base_flange, base frame, at
    the plan's linear speed caps) or ``joints`` (``target`` = joints, rad, at its joint speed
    caps); ``duration_s`` is what the move may take by the plan (the runner adds a margin for
    its timeout); ``view`` is the view to shoot after it (None: no
    shot, e.g. the way back); ``say`` is the progress line shown before the move."""

    move: str
    target: np.ndarray | None
    duration_s: float
    view: int | None = None
    pair: PairStep | None = None
    say: str = ""


MOVES = ("none", "linear", "joints")


@dataclass(frozen=True)
class Check:
    """One pre-flight check: its name, whether it passed, and the numbers behind it."""

    name: str
    ok: bool
    detail: str


def require_checks(checks: list[Check], hint: Callable[[Check], str] | None = None) -> None:
    """Raise PreflightError naming the first failed check (nothing has moved); ``hint(check)``
    is appended to its detail. Every plan and tour refuses to move through this one rule."""
    for c in checks:
        if not c.ok:
            extra = hint(c) if hint is not None else ""
            raise PreflightError(f"pre-flight check '{c.name}' failed: {c.detail}{extra}; "
                                 "nothing moved")


class Checked:
    """What every plan and tour shares: its ``checks`` decide whether anything may move."""

    checks: list[Check]

    def failure_hint(self, check: Check) -> str:
        """Extra words for the refusal of a failed ``check`` (none by default)."""
        return ""

    @property
    def ok(self) -> bool:
        return all(c.ok for c in self.checks)

    def require_ok(self) -> None:
        """Raise PreflightError naming the first failed check (nothing has moved)."""
        require_checks(self.checks, self.failure_hint)


@dataclass
class CapturePlan(Checked):
    """The checked plan: flange poses and joints per view, and every pre-flight check."""

    settings: CaptureSettings
    q_start: np.ndarray
    T_base_flange: list[np.ndarray]  # per view
    q_views: list[np.ndarray]  # IK solution per view (what the arm should reach)
    camera_positions: list[np.ndarray]  # per view, base frame
    checks: list[Check]
    duration_s: float

    def steps(self) -> list[Step]:
        """The capture as steps: shoot view 0 where the arm stands, then per pair a straight
        move by the baseline and a shot, then straight back to view 0."""
        # Each move may take as long as the whole plan (generous: a stalled move is caught).
        s, timeout = self.settings, self.duration_s
        out = [Step("none", None, timeout, view=0)]
        for k in range(1, len(self.T_base_flange)):
            out.append(Step("linear", self.T_base_flange[k], timeout, view=k,
                            pair=PairStep(k - 1, k - 1, k, s.baseline, s.direction_label),
                            say=f"moving to view {k}"))
        out.append(Step("linear", self.T_base_flange[0], timeout, say="returning to the start"))
        return out

    def describe(self) -> list[str]:
        """Human-readable lines: motion, views and checks."""
        s = self.settings
        lim = s.limits
        lines = [
            f"capture plan: {s.pairs} pair(s), {len(self.q_views)} views, baseline "
            f"{s.baseline * 1000:.1f} mm along camera {s.direction_label}",
            f"  speed caps: {lim.linear_speed:.3f} m/s, {lim.linear_acceleration:.2f} m/s^2 "
            f"(linear); settle {s.settle_s:.2f} s per view; estimated {self.duration_s:.1f} s",
            "  views (camera position in base frame, m; joints rad):",
        ]
        for k, (p, q) in enumerate(zip(self.camera_positions, self.q_views, strict=True)):
            lines.append(f"    view {k}: camera ({p[0]:+.4f}, {p[1]:+.4f}, {p[2]:+.4f})  q "
                         + " ".join(f"{v:+.3f}" for v in q))
        lines.append("  then back to view 0 along the same line")
        lines.append("  pre-flight checks:")
        lines += [f"    [{'ok' if c.ok else 'FAIL'}] {c.name}: {c.detail}" for c in self.checks]
        return lines


def plan_capture(model: ArmModel, q_start: np.ndarray, settings: CaptureSettings) -> CapturePlan:
    """Plan the views from the arm's current joints and run every pre-flight check.

    Never raises for a failed check (so --dry-run can show them all); call
    ``plan.require_ok()`` before moving. Raises ConfigError for malformed settings.
    """
    validate_settings(settings)
    q_start = np.asarray(q_start, dtype=float)
    T0 = model.flange_pose(q_start)
    R_base_camera = (T0 @ model.mount.T_flange_camera)[:3, :3]
    step = R_base_camera @ (settings.baseline * settings.direction)  # base-frame translation
    n_views = settings.pairs + 1
    poses = [_translated(T0, k * step) for k in range(n_views)]
    checks = [check_speed(settings.limits), _check_direction(settings),
              check_start(model, q_start, settings)]
    # Every view is a path sample, so the views' joints come from the path's IK.
    per_pair = max(1, math.ceil(settings.baseline / settings.path_step))
    samples = sample_path(model, q_start, T0, step, per_pair, settings.pairs)
    box = settings.workspace or Workspace.around(model)
    checks += check_path(model, samples, settings, box)
    q_views = _view_joints(q_start, samples, per_pair, n_views)
    checks.append(_check_travel(q_views, settings))
    checks.append(check_motion(model, poses))
    cams = [(T @ model.mount.T_flange_camera)[:3, 3] for T in poses]
    duration = _estimate_duration(settings, n_views)
    return CapturePlan(settings, q_start, poses, q_views, cams, checks, duration)


def validate_settings(s: CaptureSettings) -> None:
    """Raise ConfigError naming the option if ``s`` is out of range (before anything moves)."""
    validate.positive(s.baseline, "--baseline", "m", cap=MAX_BASELINE_M)
    validate.whole(s.pairs, "--pairs", 1, MAX_PAIRS)
    validate.non_negative(s.settle_s, "--settle", "s", cap=MAX_SETTLE_S)
    # The step is baseline * direction: a direction that is not a unit vector would move the
    # arm by a different distance than the baseline asked for.
    d = np.asarray(s.direction, dtype=float)
    if d.shape != (3,) or not np.all(np.isfinite(d)) or abs(np.linalg.norm(d) - 1) > UNIT_TOL:
        raise ConfigError(f"the baseline direction must be a camera-frame unit vector, got "
                          f"{s.direction!r}")
    # Speeds must be numbers > 0 here (durations divide by them); their caps are a pre-flight
    # check, so a dry run shows them beside the others.
    lim = s.limits
    validate.positive(lim.linear_speed, "--speed", "m/s")
    validate.positive(lim.linear_acceleration, "--acceleration", "m/s^2")
    validate.positive(lim.joint_speed, "joint speed", "rad/s")
    validate.positive(lim.joint_acceleration, "joint acceleration", "rad/s^2")


def _translated(T: np.ndarray, delta: np.ndarray) -> np.ndarray:
    out = T.copy()
    out[:3, 3] += delta
    return out


def check_speed(lim: MotionLimits) -> Check:
    caps = [("linear speed", lim.linear_speed, MAX_LINEAR_SPEED, "m/s"),
            ("linear acceleration", lim.linear_acceleration, MAX_LINEAR_ACCELERATION, "m/s^2"),
            ("joint speed", lim.joint_speed, MAX_JOINT_SPEED, "rad/s"),
            ("joint acceleration", lim.joint_acceleration, MAX_JOINT_ACCELERATION, "rad/s^2")]
    for name, value, cap, unit in caps:
        if not (0 < value <= cap):
            return Check("speed caps", False, f"{name} {value} {unit} is outside (0, {cap}]")
    return Check("speed caps", True, f"{lim.linear_speed} m/s <= {MAX_LINEAR_SPEED} m/s, "
                 f"{lim.linear_acceleration} m/s^2 <= {MAX_LINEAR_ACCELERATION} m/s^2")


def _check_direction(s: CaptureSettings) -> Check:
    angle = math.degrees(math.acos(min(1.0, abs(float(s.direction[2])))))
    ok = angle >= MIN_ANGLE_TO_OPTICAL_AXIS_DEG
    return Check("baseline direction", ok,
                 f"{angle:.0f} deg from the optical axis (needs >= "
                 f"{MIN_ANGLE_TO_OPTICAL_AXIS_DEG:.0f} deg: rectification needs sideways motion)")


def check_motion(model: ArmModel, poses: list[np.ndarray]) -> Check:
    """Each planned pair must be real stereo (not a pure rotation); an epipole inside the image
    (a baseline close to the optical axis) degenerates rectification, so it fails too."""
    cams = [T @ model.mount.T_flange_camera for T in poses]
    intr = model.mount.intrinsics
    for k, (a, b) in enumerate(zip(cams[:-1], cams[1:], strict=True)):
        report = classify_motion(a, b, intrinsics1=intr, intrinsics2=intr)
        if report.kind == "rotation_only" or report.epipole_in_image:
            return Check("stereo motion", False, f"pair {k}: {'; '.join(report.warnings)}")
    return Check("stereo motion", True, f"every pair is {report.kind} stereo with its epipoles "
                 "outside the image")


def check_start(model: ArmModel, q: np.ndarray, s: CaptureSettings) -> Check:
    try:
        model.check_limits(q, s.joint_margin)
    except JointLimitError as err:
        return Check("start pose", False, str(err))
    return Check("start pose", True, "current joints inside limits with "
                 f"{s.joint_margin:.2f} rad margin")


def sample_path(model: ArmModel, q_start: np.ndarray, T0: np.ndarray, step: np.ndarray,
                 per_pair: int, pairs: int) -> list[tuple[np.ndarray, np.ndarray | None, str]]:
    """IK ``per_pair`` times per baseline ``step`` along the straight flange path (sample
    ``k * per_pair`` is view ``k``): (T_base_flange, q or None, error), up to the first failure."""
    out, q = [], q_start
    for i in range(per_pair * pairs + 1):
        T = _translated(T0, (i / per_pair) * step)
        try:
            q = model.ik(T, q)
            out.append((T, q, ""))
        except IKError as err:
            out.append((T, None, str(err)))
            break
    return out


def check_path(model: ArmModel, samples, s: CaptureSettings, box: Workspace) -> list[Check]:
    failed = [x for x in samples if x[1] is None]
    if failed:
        T, _, err = failed[0]
        p = T[:3, 3]
        return [Check("IK along the path", False,
                      f"no solution at flange ({p[0]:+.3f}, {p[1]:+.3f}, {p[2]:+.3f}): {err}")]
    qs = np.array([q for _, q, _ in samples])
    margins = np.minimum(qs - model.lower, model.upper - qs).min(axis=1)
    sigmas = np.array([model.sigma_min(q) for q in qs])
    jumps = np.abs(np.diff(qs, axis=0)).max(axis=1) if len(qs) > 1 else np.zeros(1)
    flanges = [T[:3, 3] for T, _, _ in samples]
    cameras = [(T @ model.mount.T_flange_camera)[:3, 3] for T, _, _ in samples]
    outside = [p for p in flanges + cameras if not box.contains(p)]
    checks = [
        Check("IK along the path", True, f"{len(qs)} samples every {s.path_step * 1000:.0f} mm"),
        Check("joint limits", bool(margins.min() >= s.joint_margin),
              f"smallest margin {margins.min():.3f} rad (needs >= {s.joint_margin:.3f})"),
        Check("singularity", bool(sigmas.min() >= s.min_sigma),
              f"smallest Jacobian singular value {sigmas.min():.4f} (needs >= {s.min_sigma})"),
        Check("path continuity", bool(jumps.max() <= MAX_SAMPLE_JUMP_RAD),
              f"largest joint change between samples {jumps.max():.3f} rad "
              f"(needs <= {MAX_SAMPLE_JUMP_RAD})"),
    ]
    detail = f"inside {box}"
    if outside:
        p = outside[0]
        detail = f"point ({p[0]:+.3f}, {p[1]:+.3f}, {p[2]:+.3f}) leaves {box}"
    checks.append(Check("workspace", not outside, detail))
    return checks


def _view_joints(q_start: np.ndarray, samples, per_pair: int, n_views: int) -> list:
    """Joints per view, taken from the path samples; NaN from the first unreachable one."""
    qs = [q_start]
    for k in range(1, n_views):
        i = k * per_pair
        q = samples[i][1] if i < len(samples) else None
        qs.append(np.full(6, np.nan) if q is None else q)
    return qs


def _check_travel(q_views: list[np.ndarray], s: CaptureSettings) -> Check:
    travel = max(float(np.nanmax(np.abs(b - a))) if np.all(np.isfinite(b)) else np.inf
                 for a, b in zip(q_views[:-1], q_views[1:], strict=True))
    return Check("joint travel", travel <= s.max_joint_travel,
                 f"largest single-joint travel per move {travel:.3f} rad "
                 f"(needs <= {s.max_joint_travel})")


def _estimate_duration(s: CaptureSettings, n_views: int) -> float:
    lim = s.limits  # validate_settings has made sure speed and acceleration are > 0
    move = trapezoid_duration(s.baseline, lim.linear_speed, lim.linear_acceleration)
    back = trapezoid_duration(s.baseline * s.pairs, lim.linear_speed, lim.linear_acceleration)
    return (n_views - 1) * move + back + n_views * s.settle_s
