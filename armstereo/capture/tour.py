"""A scan's whole tour, checked before anything moves, and the capture steps that run it.

``armstereo scan`` visits the kept viewpoints of a :class:`~armstereo.capture.scan_plan.ScanPlan`
in tour order: from the start joints a joint move (moveJ) to the first viewpoint's left view,
a shot, a straight camera move by the baseline along the camera's x to its right view, a shot,
a pair event tagged with the viewpoint; then a joint move to the next viewpoint's left view, and
so on; after the last viewpoint a joint move back to the start joints. Views are numbered in
shooting order (viewpoint ``k`` of the tour: views ``2k``, ``2k + 1``, pair ``k``).

Every move of the tour is checked as capture checks its line (``armstereo.capture.plan``):

- **baseline moves** (straight flange paths): IK every ``path_step`` m (warm-started, as the
  arm's linear move follows the path), joint limits with margin, singularity, path continuity,
  workspace box (flange and camera), joint travel per move;
- **joint moves** (start -> viewpoint -> ... -> start): the straight joint-space path moveJ
  follows, sampled every ``JOINT_PATH_STEP_RAD`` of its largest joint: joint limits with
  margin, singularity, workspace box (flange and camera; a joint move between two reachable
  poses can sweep the camera through the table);
- speed caps, the start pose, and at least one viewpoint kept.

A failed check names the move (``start -> viewpoint 3``, ``viewpoint 3 baseline``, ...). All
poses are in the controller's ``base`` frame; lengths m, angles rad, times s.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from armstereo.capture.plan import (
    MAX_SAMPLE_JUMP_RAD,
    CaptureSettings,
    Check,
    Checked,
    PairStep,
    Step,
    Workspace,
    check_motion,
    check_speed,
    check_start,
    sample_path,
    validate_settings,
)
from armstereo.capture.scan_plan import ScanPlan, ScanView, order_tour
from armstereo.devices import trapezoid_duration
from armstereo.robot.arm_model import ArmModel

JOINT_PATH_STEP_RAD = 0.01  # joint-move samples: at most this change of any joint apart
MAX_DROPPED_SHOWN = 3  # dropped viewpoints named in a refusal
REORDER_ROUNDS = 5  # tour orderings tried with the failing joint moves forbidden


@dataclass(frozen=True)
class Leg:
    """One move of the tour: ``kind`` ``joints`` or ``linear``, a ``label`` naming it, its
    joint samples (n, 6) rad (None where IK failed part way: ``error`` says where), and its
    planned duration (s)."""

    kind: str
    label: str
    samples: np.ndarray | None
    duration_s: float
    error: str = ""


@dataclass
class ScanTour(Checked):
    """A scan plan checked as one tour: what :func:`armstereo.capture.run.run_capture` runs.

    ``scan`` holds the viewpoints in the order they are visited (routing may have reordered
    them or dropped some, see :func:`plan_tour`); ``settings`` the baseline, settle time, speed
    caps, margins and workspace; ``legs`` every move in order, each with its capture step in
    ``step_list``.
    """

    scan: ScanPlan
    settings: CaptureSettings
    q_start: np.ndarray
    legs: list[Leg]
    step_list: list[Step]
    checks: list[Check]
    duration_s: float
    detours: int = 0

    def failure_hint(self, check: Check) -> str:
        return _no_order_hint(check)

    def steps(self) -> list[Step]:
        """The tour as capture steps (module docstring)."""
        return list(self.step_list)

    def describe(self) -> list[str]:
        """Human-readable lines: the scan plan (kept and dropped viewpoints), the speed caps,
        the estimated duration and every pre-flight check."""
        lim = self.settings.limits
        lines = self.scan.describe()
        if self.detours:
            lines.append(f"  {self.detours} joint move(s) go by way of the start pose (the "
                         "direct move failed a check)")
        lines += [f"  speed caps: {lim.joint_speed:.2f} rad/s, {lim.joint_acceleration:.2f} "
                  f"rad/s^2 (joint moves); {lim.linear_speed:.3f} m/s, "
                  f"{lim.linear_acceleration:.2f} m/s^2 (baseline moves); settle "
                  f"{self.settings.settle_s:.2f} s per view; estimated {self.duration_s:.1f} s",
                  "  tour pre-flight checks:"]
        lines += [f"    [{'ok' if c.ok else 'FAIL'}] {c.name}: {c.detail}" for c in self.checks]
        return lines


def plan_tour(model: ArmModel, scan: ScanPlan, settings: CaptureSettings) -> ScanTour:
    """Route and check the whole tour of ``scan`` (planned from ``scan.q_start``) with
    ``settings`` (baseline = the scan's; its ``pairs`` and ``direction`` are ignored: one pair
    per viewpoint, along camera x).

    Routing: a joint move between two viewpoints that fails a check (it passes near a
    singularity, leaves the workspace) is avoided by ordering the viewpoints again with that
    move forbidden (up to REORDER_ROUNDS times); one that is still needed goes by way of the
    start pose if both halves pass. Then every move of the routed tour is checked: a move no
    route avoids fails the tour (the caller refuses it, nothing moves).

    Never raises for a failed check (a dry run shows them all); call ``tour.require_ok()``
    before moving. Raises ConfigError for malformed settings.
    """
    settings = replace(settings, baseline=scan.baseline, direction=np.array([1.0, 0.0, 0.0]),
                       direction_label="x", pairs=max(1, len(scan.views)))
    validate_settings(replace(settings, pairs=1))  # a scan may have more pairs than a line
    box = settings.workspace or Workspace.around(model)
    baselines = {v.index: baseline_leg(model, v, settings) for v in scan.views}
    router = _Router(model, scan, baselines, settings, box)
    scan = router.route()
    legs, steps = router.assemble(scan)
    scan = replace(scan, tour_joint_travel_rad=sum(
        float(np.abs(leg.samples[-1] - leg.samples[0]).max()) for leg in legs
        if leg.kind == "joints"))
    checks = [check_speed(settings.limits), check_start(model, scan.q_start, settings),
              _check_viewpoints(scan)]
    if scan.views:
        checks += check_legs(model, legs, settings, box)
        checks.append(_check_pairs_are_stereo(model, scan))
    duration = sum(leg.duration_s for leg in legs) + 2 * len(scan.views) * settings.settle_s
    return ScanTour(scan, settings, np.asarray(scan.q_start, float), legs, steps, checks,
                    duration, len(router.via_start))


def _check_pairs_are_stereo(model: ArmModel, scan) -> Check:
    """Each viewpoint's two views must be real stereo with the epipoles outside the images
    (the same rule as a line capture's pre-flight)."""
    T_camera_flange = np.linalg.inv(model.mount.T_flange_camera)
    for view in scan.views:
        check = check_motion(model, [view.T_base_left @ T_camera_flange,
                                     view.T_base_right @ T_camera_flange])
        if not check.ok:
            return Check(check.name, False, f"viewpoint {view.index}: {check.detail}")
    return Check("stereo motion", True, "every viewpoint's pair is stereo with its epipoles "
                 "outside the images")


class _Router:
    """Orders, detours and drops viewpoints so that every joint move passes its checks."""

    def __init__(self, model: ArmModel, scan: ScanPlan, baselines: dict[int, Leg],
                 s: CaptureSettings, box: Workspace):
        self.model, self.scan, self.baselines, self.s, self.box = model, scan, baselines, s, box
        self.q_start = np.asarray(scan.q_start, float)
        self._failed: dict[tuple, Check | None] = {}
        self.via_start: set[int] = set()

    def q_end(self, v: ScanView | None) -> np.ndarray:
        """Joints where the arm stands after viewpoint ``v`` (None: the start)."""
        if v is None:
            return self.q_start
        leg = self.baselines[v.index]
        return v.q_right if leg.samples is None else leg.samples[-1]

    def failure(self, a: ScanView | None, b: ScanView | None) -> Check | None:
        """The first failed check of the joint move from ``a`` to ``b`` (None = start)."""
        key = (_name(a), _name(b))
        if key not in self._failed:
            leg = joint_leg(self.q_end(a), self.q_start if b is None else b.q_left,
                            f"{key[0]} -> {key[1]}", self.s)
            bad = [c for c in check_legs(self.model, [leg], self.s, self.box) if not c.ok]
            self._failed[key] = bad[0] if bad else None
        return self._failed[key]

    def route(self) -> ScanPlan:
        """The viewpoints reordered, with ``via_start`` naming those reached by way of the
        start pose; a move no route avoids stays (its check fails the tour)."""
        views = self._reorder(list(self.scan.views))
        prev: ScanView | None = None
        for v in views:
            if self.failure(prev, v) is not None and prev is not None \
                    and self.failure(prev, None) is None and self.failure(None, v) is None:
                self.via_start.add(v.index)
            prev = v
        return replace(self.scan, views=views)

    def _reorder(self, views: list[ScanView]) -> list[ScanView]:
        forbidden: set[tuple] = set()
        for _ in range(REORDER_ROUNDS):
            stops = [None, *views, None]
            bad = {(_name(a), _name(b)) for a, b in zip(stops[:-1], stops[1:], strict=True)
                   if self.failure(a, b) is not None}
            if not bad or bad <= forbidden:
                break
            forbidden |= bad
            pos = {_name(v): i for i, v in enumerate(views)}
            pos["start"] = None
            order, _ = order_tour(self.q_start, [v.q_left for v in views],
                                  [self.q_end(v) for v in views],
                                  {(pos[a], pos[b]) for a, b in forbidden})
            views = [views[i] for i in order]
        return views

    def assemble(self, scan: ScanPlan) -> tuple[list[Leg], list[Step]]:
        """The routed tour's moves and capture steps, in order."""
        s, legs, steps = self.s, [], []
        prev: ScanView | None = None
        for k, v in enumerate(scan.views):
            if v.index in self.via_start:
                leg = joint_leg(self.q_end(prev), self.q_start,
                                f"{_name(prev)} -> start (detour)", s)
                legs.append(leg)
                steps.append(Step("joints", self.q_start, leg.duration_s,
                                  say=f"by way of the start pose to viewpoint {v.index}"))
                prev = None
            leg = joint_leg(self.q_end(prev), v.q_left, f"{_name(prev)} -> {_name(v)}", s)
            legs.append(leg)
            steps.append(Step("joints", v.q_left, leg.duration_s, view=2 * k,
                              say=f"moving to viewpoint {v.index} ({k + 1}/"
                              f"{len(scan.views)})"))
            base = self.baselines[v.index]
            legs.append(base)
            steps.append(Step("linear", self.model.flange_pose_for_camera(v.T_base_right),
                              base.duration_s, view=2 * k + 1,
                              pair=PairStep(k, 2 * k, 2 * k + 1, s.baseline, s.direction_label,
                                            v.index),
                              say=f"baseline move at viewpoint {v.index}"))
            prev = v
        if scan.views:
            leg = joint_leg(self.q_end(prev), self.q_start, f"{_name(prev)} -> start", s)
            legs.append(leg)
            steps.append(Step("joints", self.q_start, leg.duration_s,
                              say="returning to the start"))
        return legs, steps


def _name(v: ScanView | None) -> str:
    return "start" if v is None else f"viewpoint {v.index}"


def joint_path(q_from: np.ndarray, q_to: np.ndarray,
               step: float = JOINT_PATH_STEP_RAD) -> np.ndarray:
    """Samples (n, 6) rad of the straight joint-space path moveJ follows from ``q_from`` to
    ``q_to``, at most ``step`` rad of any joint apart, both ends included."""
    q_from, q_to = np.asarray(q_from, float), np.asarray(q_to, float)
    n = max(1, math.ceil(float(np.abs(q_to - q_from).max()) / step))
    s = np.arange(n + 1)[:, None] / n
    return q_from + s * (q_to - q_from)


def baseline_leg(model: ArmModel, view: ScanView, s: CaptureSettings) -> Leg:
    """The straight camera move of ``view`` from its left to its right view, IK sampled every
    ``s.path_step`` m from the left view's joints (warm-started, as the arm's linear move
    follows it)."""
    lim = s.limits
    per_move = max(1, math.ceil(s.baseline / s.path_step))
    duration = trapezoid_duration(s.baseline, lim.linear_speed, lim.linear_acceleration)
    T_left = model.flange_pose_for_camera(view.T_base_left)
    step = view.T_base_right[:3, 3] - view.T_base_left[:3, 3]
    samples = sample_path(model, view.q_left, T_left, step, per_move, 1)
    label = f"viewpoint {view.index} baseline"
    failed = [err for _, q, err in samples if q is None]
    if failed:
        return Leg("linear", label, None, duration, failed[0])
    return Leg("linear", label, np.array([q for _, q, _ in samples]), duration)


def joint_leg(q_from: np.ndarray, q_to: np.ndarray, label: str, s: CaptureSettings) -> Leg:
    """The joint move (moveJ) from ``q_from`` to ``q_to`` (rad) at ``s``'s joint speed caps."""
    q_from, q_to = np.asarray(q_from, float), np.asarray(q_to, float)
    travel = float(np.abs(q_to - q_from).max())
    lim = s.limits
    return Leg("joints", label, joint_path(q_from, q_to),
               trapezoid_duration(travel, lim.joint_speed, lim.joint_acceleration))


def _check_viewpoints(scan: ScanPlan) -> Check:
    total = len(scan.views) + len(scan.dropped)
    if scan.views:
        return Check("viewpoints", True, f"{len(scan.views)} of {total} kept"
                     + (f" ({len(scan.dropped)} dropped, see above)" if scan.dropped else ""))
    reasons = "; ".join(f"viewpoint {d.index}: {d.check}: {d.reason}"
                        for d in scan.dropped[:MAX_DROPPED_SHOWN])
    more = len(scan.dropped) - MAX_DROPPED_SHOWN
    return Check("viewpoints", False, f"none of the {total} viewpoints of {scan.layout} around "
                 f"the target is reachable ({reasons}" + (f"; {more} more" if more > 0 else "")
                 + ")")


def check_legs(model: ArmModel, legs: list[Leg], s: CaptureSettings,
               box: Workspace) -> list[Check]:
    """IK, joint limits, singularity, continuity, workspace and travel over every move of
    ``legs`` (the continuity and travel checks over the baseline moves among them)."""
    failed = [leg for leg in legs if leg.samples is None]
    if failed:
        return [Check("IK along the baseline moves", False, f"{failed[0].label}: "
                      f"{failed[0].error}")]
    baselines = [leg for leg in legs if leg.kind == "linear"]
    checks = []
    if baselines:
        checks.append(Check("IK along the baseline moves", True,
                            f"{sum(len(leg.samples) for leg in baselines)} samples every "
                            f"{s.path_step * 1000:.0f} mm on {len(baselines)} baseline moves; "
                            f"joint moves sampled every {JOINT_PATH_STEP_RAD} rad"))
    margin, margin_at = min((_margin(model, leg.samples), leg.label) for leg in legs)
    checks.append(Check("joint limits", margin >= s.joint_margin,
                        f"smallest margin {margin:.3f} rad on {margin_at} (needs >= "
                        f"{s.joint_margin:.3f})"))
    sigma, sigma_at = min((min(model.sigma_min(q) for q in leg.samples), leg.label)
                          for leg in legs)
    checks.append(Check("singularity", sigma >= s.min_sigma,
                        f"smallest Jacobian singular value {sigma:.4f} on {sigma_at} (needs >= "
                        f"{s.min_sigma})"))
    if baselines:
        jump, jump_at = max((float(np.abs(np.diff(leg.samples, axis=0)).max()), leg.label)
                            for leg in baselines)
        checks.append(Check("path continuity", jump <= MAX_SAMPLE_JUMP_RAD,
                            f"largest joint change between samples {jump:.3f} rad on {jump_at} "
                            f"(needs <= {MAX_SAMPLE_JUMP_RAD})"))
    checks.append(_check_workspace(model, legs, box))
    if baselines:
        travel, travel_at = max((float(np.abs(leg.samples[-1] - leg.samples[0]).max()),
                                 leg.label) for leg in baselines)
        checks.append(Check("joint travel", travel <= s.max_joint_travel,
                            f"largest single-joint travel per baseline move {travel:.3f} rad on "
                            f"{travel_at} (needs <= {s.max_joint_travel})"))
    return checks


def _margin(model: ArmModel, qs: np.ndarray) -> float:
    return float(np.minimum(qs - model.lower, model.upper - qs).min())


def _check_workspace(model: ArmModel, legs: list[Leg], box: Workspace) -> Check:
    T_fc = model.mount.T_flange_camera
    for leg in legs:
        for q in leg.samples:
            T = model.flange_pose(q)
            for what, p in (("flange", T[:3, 3]), ("camera", (T @ T_fc)[:3, 3])):
                if not box.contains(p):
                    return Check("workspace", False, f"{what} at ({p[0]:+.3f}, {p[1]:+.3f}, "
                                 f"{p[2]:+.3f}) on {leg.label} leaves {box}")
    return Check("workspace", True, f"flange and camera inside {box} on every move")


def _no_order_hint(check: Check) -> str:
    """A failed move between two viewpoints (" -> " in its detail) has no way round it."""
    if " -> " not in check.detail:
        return ""
    return ("; no order of the viewpoints avoids that move (choose other --views, --elevation "
            "or --radius, or a --workspace that leaves the viewpoint out)")

