"""Viewpoints for a multi-view scan: stereo pairs around a target, filtered and ordered.

Pure planning (nothing moves). Each viewpoint is a camera position on a sphere of ``radius``
metres around a base-frame ``target``, looking at it; the pair's two views share that
orientation and sit ``baseline / 2`` either side of the viewpoint along the camera's x axis
(image right), so the pair is a sideways stereo pair the rectifier handles without rotation.

Camera orientation (OpenCV optical frame, base frame ``base``): z points at the target; y is
the component of "down" (-z of base) across the optical axis, so image up is world up; at the
top of the sphere (elevation 90 deg, where "down" is the optical axis) y points away from the
target horizontally along the viewpoint's azimuth. Azimuth is measured about base z from base
+x, elevation above the target's horizontal plane. Where the wrist cannot reach that
orientation, the camera may be rolled about its optical axis (``ROLLS_DEG``); the kept roll is
the one whose joints are nearest the start joints among those keeping the baseline level (0 or
180 deg), a quarter turn only where neither level roll is reachable.

Layouts (``parse_views``):

- ``ring:N``: N azimuths evenly spaced at one elevation;
- ``sphere:N``: N directions spread evenly (golden-angle spiral) over the spherical cap from
  the given elevation up to the top;
- ``grid:RxC``: R elevations evenly spaced from the given one to ``GRID_TOP_ELEVATION_DEG``, C
  azimuths each (rows offset by half a step, so no two rows line up).

Each viewpoint (at some roll) is kept only if both views and the straight baseline move
between them pass IK, joint limits with margin, the singularity bound, and stay inside the
workspace box; a dropped viewpoint carries the check that failed and why. The kept views
are ordered for a short tour in joint space (nearest neighbour from the start joints, then
2-opt, returning to the start).
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from armstereo.capture.plan import Workspace
from armstereo.errors import ConfigError, IKError
from armstereo.robot.arm_model import ArmModel, ready_configuration
from armstereo.transforms import make_T, rot_z

MAX_VIEWPOINTS = 200
GRID_TOP_ELEVATION_DEG = 80.0  # grid rows stop short of the top, where azimuths bunch up
MIN_RADIUS_M = 0.05
MAX_RADIUS_M = 2.0
DEFAULT_RADIUS_M = 0.45
DEFAULT_ELEVATION_DEG = 55.0
DEFAULT_BASELINE_M = 0.06
PATH_STEP_M = 0.005  # IK sample spacing along the baseline move (as capture checks it)
MAX_SAMPLE_JUMP_RAD = 0.15  # a larger joint jump between path samples is a branch flip
TWO_OPT_ROUNDS = 50
FORBIDDEN_LEG_RAD = 1e3  # extra cost of a leg the tour's pre-flight refused
# Camera rolls about the optical axis tried per viewpoint (deg): the wrist reaches some
# viewpoints only with the image turned; the baseline stays along the (turned) camera x.
ROLLS_DEG = (0.0, 180.0, 90.0, -90.0)
# Rolls that keep the baseline horizontal (camera x level). At +-90 deg the baseline runs up
# the elevation arc: the views differ in elevation, so walls and tops are foreshortened
# differently in the two images and the row-wise matcher loses most of every wall facing the
# pair (bench/results/fused_footprint.md: four of the twelve ring views lost a crate wall).
LEVEL_ROLLS_DEG = (0.0, 180.0)
_VIEWS_RE = re.compile(r"^(ring|sphere):(\d+)$|^grid:(\d+)x(\d+)$")


@dataclass(frozen=True)
class ViewLayout:
    """A parsed ``--views`` value: ``kind`` ring/sphere/grid, ``rows`` x ``cols`` viewpoints
    (ring and sphere have one row)."""

    kind: str
    rows: int
    cols: int

    @property
    def count(self) -> int:
        return self.rows * self.cols

    def __str__(self) -> str:
        return f"grid:{self.rows}x{self.cols}" if self.kind == "grid" else \
            f"{self.kind}:{self.cols}"


def parse_views(text: str) -> ViewLayout:
    """``ring:N``, ``sphere:N`` or ``grid:RxC`` -> :class:`ViewLayout`; ConfigError otherwise."""
    m = _VIEWS_RE.match(text.strip().lower())
    if not m:
        raise ConfigError(f"--views must be ring:N, sphere:N or grid:RxC, not {text!r}")
    layout = (ViewLayout(m.group(1), 1, int(m.group(2))) if m.group(1)
              else ViewLayout("grid", int(m.group(3)), int(m.group(4))))
    if not 1 <= layout.count <= MAX_VIEWPOINTS:
        raise ConfigError(f"--views {text!r} asks for {layout.count} viewpoints; "
                          f"use 1..{MAX_VIEWPOINTS}")
    return layout


def look_at_pose(target: np.ndarray, azimuth: float, elevation: float, radius: float,
                 roll: float = 0.0) -> np.ndarray:
    """T_base_camera (OpenCV optical frame) at ``radius`` m from ``target`` (base, m) along
    (azimuth, elevation) (rad), looking at the target; axes as in the module docstring, then
    turned by ``roll`` rad about the optical axis."""
    ca, sa, ce, se = math.cos(azimuth), math.sin(azimuth), math.cos(elevation), math.sin(elevation)
    outward = np.array([ce * ca, ce * sa, se])
    z = -outward
    y = np.array([se * ca, se * sa, -ce])  # "down" across the optical axis, unit length
    x = np.cross(y, z)
    R = np.column_stack([x, y, z]) @ rot_z(roll)
    return make_T(R, np.asarray(target, float) + radius * outward)


def layout_directions(layout: ViewLayout, elevation_deg: float) -> list[tuple[float, float]]:
    """(azimuth, elevation) in radians of every viewpoint of ``layout``, in generation order."""
    e0 = math.radians(elevation_deg)
    if layout.kind == "ring":
        n = layout.cols
        return [(2 * math.pi * k / n, e0) for k in range(n)]
    if layout.kind == "sphere":
        n = layout.cols
        # Even area on the cap from e0 to the top: sin(elevation) uniform in [sin e0, 1].
        golden = math.pi * (3.0 - math.sqrt(5.0))
        out = []
        for k in range(n):
            s = math.sin(e0) + (1.0 - math.sin(e0)) * (k + 0.5) / n
            out.append(((k * golden) % (2 * math.pi), math.asin(min(1.0, s))))
        return out
    top = max(e0, math.radians(GRID_TOP_ELEVATION_DEG))
    rows = [e0] if layout.rows == 1 else list(np.linspace(e0, top, layout.rows))
    step = 2 * math.pi / layout.cols
    return [((c + 0.5 * (r % 2)) * step, float(el)) for r, el in enumerate(rows)
            for c in range(layout.cols)]


@dataclass(frozen=True)
class ScanView:
    """A kept viewpoint: its stereo pair's camera poses (base frame) and joints (rad).

    ``index`` numbers the viewpoint in generation order (stable across re-planning);
    ``T_base_camera`` is the viewpoint itself (between the two views); the left view is
    shot first, then the camera moves ``baseline`` along its x axis to the right view.
    """

    index: int
    azimuth_deg: float
    elevation_deg: float
    roll_deg: float
    T_base_camera: np.ndarray
    T_base_left: np.ndarray
    T_base_right: np.ndarray
    q_left: np.ndarray
    q_right: np.ndarray
    sigma_min: float
    joint_margin: float


@dataclass(frozen=True)
class DroppedView:
    """A viewpoint that was not kept: which check failed (``check``) and why (``reason``)."""

    index: int
    azimuth_deg: float
    elevation_deg: float
    check: str
    reason: str


@dataclass
class ScanPlan:
    """Kept views in tour order, dropped viewpoints, and the tour's joint-space length."""

    target: np.ndarray
    radius: float
    baseline: float
    layout: ViewLayout
    elevation_deg: float
    q_start: np.ndarray
    views: list[ScanView]
    dropped: list[DroppedView]
    tour_joint_travel_rad: float = field(default=0.0)

    def describe(self) -> list[str]:
        """Human-readable lines: the layout, every kept view in tour order, every dropped one."""
        t = self.target
        lines = [f"scan plan: {self.layout} around ({t[0]:+.3f}, {t[1]:+.3f}, {t[2]:+.3f}) m, "
                 f"radius {self.radius:.3f} m, elevation {self.elevation_deg:.0f} deg, baseline "
                 f"{self.baseline * 1000:.0f} mm: {len(self.views)} of "
                 f"{len(self.views) + len(self.dropped)} viewpoints kept",
                 f"  tour: {self.tour_joint_travel_rad:.2f} rad of largest-joint travel, "
                 "start -> views -> start"]
        for v in self.views:
            p = v.T_base_camera[:3, 3]
            lines.append(f"    viewpoint {v.index}: azimuth {v.azimuth_deg:6.1f} deg, elevation "
                         f"{v.elevation_deg:4.1f} deg, roll {v.roll_deg:4.0f} deg, camera "
                         f"({p[0]:+.3f}, {p[1]:+.3f}, {p[2]:+.3f}), sigma_min "
                         f"{v.sigma_min:.3f}, joint margin {v.joint_margin:.2f} rad")
        for d in self.dropped:
            lines.append(f"    dropped viewpoint {d.index} (azimuth {d.azimuth_deg:.1f} deg, "
                         f"elevation {d.elevation_deg:.1f} deg): {d.check}: {d.reason}")
        return lines


@dataclass(frozen=True)
class ScanSettings:
    """Limits the viewpoints must respect (rad, m; as capture's pre-flight uses them)."""

    joint_margin: float = 0.05
    min_sigma: float = 0.02
    path_step: float = PATH_STEP_M
    workspace: Workspace | None = None  # None: Workspace.around(model)


def plan_scan(model: ArmModel, q_start: np.ndarray, target, *, views: str | ViewLayout = "ring:12",
              radius: float = DEFAULT_RADIUS_M, elevation_deg: float = DEFAULT_ELEVATION_DEG,
              baseline: float = DEFAULT_BASELINE_M,
              settings: ScanSettings = ScanSettings()) -> ScanPlan:
    """Plan a scan of ``target`` (base frame, m) from joints ``q_start`` (rad).

    Raises ConfigError for malformed options (never for an unreachable view: those are
    listed in ``plan.dropped``; an empty ``plan.views`` is the caller's to refuse).
    """
    layout = views if isinstance(views, ViewLayout) else parse_views(views)
    target = _check_target(target)
    _check_options(radius, elevation_deg, baseline)
    q_start = np.asarray(q_start, dtype=float).reshape(-1)
    box = settings.workspace or Workspace.around(model)
    directions = layout_directions(layout, elevation_deg)
    results: dict[int, ScanView | _Failure] = {}
    # Second pass: a viewpoint IK could not reach from the generic seeds is retried from the
    # joints of the kept viewpoints nearest to it (damped least squares needs a nearby seed).
    for attempt in range(2):
        solved = [r for r in results.values() if isinstance(r, ScanView)]
        for k, (az, el) in enumerate(directions):
            if attempt == 1 and (not isinstance(results[k], _Failure) or not solved):
                continue
            results[k] = _best_roll(model, q_start, k, az, el, target, radius, baseline,
                                    settings, box, solved if attempt else [])
    kept = [r for r in results.values() if isinstance(r, ScanView)]
    dropped = [DroppedView(k, math.degrees(directions[k][0]), math.degrees(directions[k][1]),
                           r.check, r.reason)
               for k, r in sorted(results.items()) if isinstance(r, _Failure)]
    order, travel = order_tour(q_start, [v.q_left for v in kept], [v.q_right for v in kept])
    return ScanPlan(target, radius, baseline, layout, elevation_deg, q_start,
                    [kept[i] for i in order], dropped, travel)


class _Failure(NamedTuple):
    check: str
    reason: str


def _check_target(target) -> np.ndarray:
    t = np.asarray(target, dtype=float).reshape(-1)
    if t.shape != (3,) or not np.all(np.isfinite(t)):
        raise ConfigError(f"--target must be three finite numbers X,Y,Z (m), got {target!r}")
    return t


def _check_options(radius: float, elevation_deg: float, baseline: float) -> None:
    if not MIN_RADIUS_M <= radius <= MAX_RADIUS_M:
        raise ConfigError(f"--radius must be in [{MIN_RADIUS_M}, {MAX_RADIUS_M}] m, got {radius}")
    if not 0.0 <= elevation_deg <= 90.0:
        raise ConfigError(f"--elevation must be in [0, 90] deg, got {elevation_deg}")
    if not 0.0 < baseline < radius:
        raise ConfigError(f"--baseline must be in (0, radius = {radius}) m, got {baseline}")


def _best_roll(model: ArmModel, q_start: np.ndarray, k: int, az: float, el: float,
               target: np.ndarray, radius: float, baseline: float, s: ScanSettings,
               box: Workspace, solved: list[ScanView]) -> ScanView | _Failure:
    """The viewpoint at the camera roll (of ROLLS_DEG) whose left-view joints are nearest the
    start joints, a level baseline (LEVEL_ROLLS_DEG) first when one is reachable; or the
    failure of the first roll tried (the upright camera)."""
    best: ScanView | None = None
    first: _Failure | None = None
    for roll in ROLLS_DEG:
        T = look_at_pose(target, az, el, radius, math.radians(roll))
        seeds = _neighbour_seeds(solved, T)
        result = _check_viewpoint(model, q_start, T, baseline, s, box, seeds)
        if isinstance(result, _Failure):
            first = first or result
            continue
        view = ScanView(k, math.degrees(az), math.degrees(el), float(roll), T, *result)
        if best is None or _roll_rank(view, q_start) < _roll_rank(best, q_start):
            best = view
    if best is not None:
        return best
    rolls = ", ".join(f"{r:.0f}" for r in ROLLS_DEG)
    return _Failure(first.check, f"no camera roll ({rolls} deg) works; upright: {first.reason}")


def _roll_rank(view: ScanView, q_start: np.ndarray) -> tuple[bool, float]:
    """Sort key of a reachable roll: a level baseline first, then the joints nearest start."""
    return view.roll_deg not in LEVEL_ROLLS_DEG, _joint_distance(view.q_left, q_start)


def _check_viewpoint(model: ArmModel, q_start: np.ndarray, T_cam: np.ndarray,
                     baseline: float, s: ScanSettings, box: Workspace,
                     extra_seeds: list[np.ndarray]):
    """The kept view's (T_left, T_right, q_left, q_right, sigma, margin), or the failed check."""
    shift = T_cam[:3, 0] * baseline / 2
    T_left, T_right = T_cam.copy(), T_cam.copy()
    T_left[:3, 3] -= shift
    T_right[:3, 3] += shift
    for name, T in (("left", T_left), ("right", T_right)):
        for what, p in (("camera", T[:3, 3]),
                        ("flange", model.flange_pose_for_camera(T)[:3, 3])):
            if not box.contains(p):
                return _Failure("workspace", f"{name} view {what} at ({p[0]:+.3f}, {p[1]:+.3f}, "
                        f"{p[2]:+.3f}) leaves {box}")
    q_left = _solve_view(model, q_start, T_left, s.joint_margin, extra_seeds)
    if isinstance(q_left, str):
        return _Failure("IK", f"left view: {q_left}")
    path = _baseline_path(model, q_left, T_left, T_right, s)
    if isinstance(path, _Failure):
        return path
    margins = np.minimum(path - model.lower, model.upper - path).min()
    if margins < s.joint_margin:
        return _Failure("joint limits", f"smallest margin {margins:.3f} rad along the baseline "
                        f"move (needs >= {s.joint_margin:.3f})")
    sigma = min(model.sigma_min(q) for q in path)
    if sigma < s.min_sigma:
        return _Failure("singularity", f"smallest Jacobian singular value {sigma:.4f} (needs >= "
                f"{s.min_sigma})")
    return T_left, T_right, path[0], path[-1], float(sigma), float(margins)


def _seeds(model: ArmModel, q_start: np.ndarray, T_cam: np.ndarray) -> list[np.ndarray]:
    """IK seeds: the start joints, and the ready pose turned (shoulder pan) towards the camera."""
    seeds = [q_start]
    try:
        ready = ready_configuration(model.name)
    except ConfigError:  # a custom URDF has no ready pose: the start joints must do
        return seeds
    p_ready = model.flange_pose(ready)[:3, 3]
    p = T_cam[:3, 3]
    turn = math.atan2(p[1], p[0]) - math.atan2(p_ready[1], p_ready[0])
    q = ready.copy()
    q[0] = q[0] + math.remainder(turn, 2 * math.pi)
    seeds.append(q)
    seeds.append(ready)
    return seeds


def _neighbour_seeds(solved: list[ScanView], T_cam: np.ndarray,
                     count: int = 3) -> list[np.ndarray]:
    """Left-view joints of the ``count`` kept viewpoints whose cameras are nearest ``T_cam``."""
    near = sorted(solved, key=lambda v: float(np.linalg.norm(v.T_base_camera[:3, 3]
                                                              - T_cam[:3, 3])))
    return [v.q_left for v in near[:count]]


def _solve_view(model: ArmModel, q_start: np.ndarray, T_cam: np.ndarray, margin: float,
                extra_seeds: list[np.ndarray]):
    """Joints for the camera at ``T_cam``: the IK solution (over all seeds) nearest the start
    joints, or the last failure's text."""
    T_flange = model.flange_pose_for_camera(T_cam)
    best, error = None, "no seed"
    for seed in [*_seeds(model, q_start, T_cam), *extra_seeds]:
        try:
            q = model.ik(T_flange, seed, margin=margin, max_iter=400)
        except IKError as err:
            error = str(err)
            continue
        if best is None or _joint_distance(q, q_start) < _joint_distance(best, q_start):
            best = q
    return best if best is not None else error


def _baseline_path(model: ArmModel, q_left: np.ndarray, T_left: np.ndarray,
                   T_right: np.ndarray, s: ScanSettings):
    """Joints (n, 6) every ``path_step`` along the straight camera move from left to right
    (warm-started IK, as the arm's linear move follows it), or the failed check."""
    n = max(1, math.ceil(np.linalg.norm(T_right[:3, 3] - T_left[:3, 3]) / s.path_step))
    qs, q = [q_left], q_left
    for i in range(1, n + 1):
        T = T_left.copy()
        T[:3, 3] += (T_right[:3, 3] - T_left[:3, 3]) * i / n
        try:
            q_next = model.ik(model.flange_pose_for_camera(T), q, margin=0.0)
        except IKError as err:
            return _Failure("IK", f"baseline move, {i * 100 // n} % of the way to the right "
                            f"view: {err}")
        if np.abs(q_next - q).max() > MAX_SAMPLE_JUMP_RAD:
            jump = float(np.abs(q_next - q).max())
            return _Failure("path continuity", f"joint jump {jump:.3f} rad between samples "
                            f"{s.path_step * 1000:.0f} mm apart (needs <= "
                            f"{MAX_SAMPLE_JUMP_RAD})")
        qs.append(q_next)
        q = q_next
    return np.array(qs)


def _joint_distance(a: np.ndarray, b: np.ndarray) -> float:
    """Largest single-joint change (rad): what a synchronised joint move's duration scales with."""
    return float(np.abs(np.asarray(a) - np.asarray(b)).max())


def order_tour(q_start: np.ndarray, q_first: list[np.ndarray],
               q_last: list[np.ndarray],
               forbidden: set[tuple[int | None, int | None]] = frozenset()
               ) -> tuple[list[int], float]:
    """Order views (each entered at ``q_first[i]`` and left at ``q_last[i]``) for a short
    start -> views -> start tour; returns (order, joint travel in rad).

    Nearest neighbour from the start, then 2-opt (segment reversal) until no reversal helps.
    Reversing a segment keeps each view's own left-to-right direction; the cost of a leg is
    the largest single-joint change. ``forbidden`` legs ``(from, to)`` (None = the start) cost
    FORBIDDEN_LEG_RAD extra, so they are used only where no order avoids them.
    """
    n = len(q_first)
    if n == 0:
        return [], 0.0
    start = np.asarray(q_start, float)

    def leg(a: int | None, b: int | None) -> float:
        qa = start if a is None else q_last[a]
        qb = start if b is None else q_first[b]
        return _joint_distance(qa, qb) + (FORBIDDEN_LEG_RAD if (a, b) in forbidden else 0.0)

    order, left = [], set(range(n))
    current: int | None = None
    while left:
        nxt = min(left, key=lambda j: (leg(current, j), j))
        order.append(nxt)
        left.remove(nxt)
        current = nxt

    def cost(seq: list[int]) -> float:
        stops: list[int | None] = [None, *seq, None]
        return sum(leg(a, b) for a, b in zip(stops[:-1], stops[1:], strict=True))

    best = cost(order)
    for _ in range(TWO_OPT_ROUNDS):
        improved = False
        for i in range(n - 1):
            for j in range(i + 1, n):
                cand = order[:i] + order[i:j + 1][::-1] + order[j + 1:]
                c = cost(cand)
                if c < best - 1e-12:
                    order, best, improved = cand, c, True
        if not improved:
            break
    return order, best

