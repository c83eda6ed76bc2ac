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
    PairStep,
    Step,
    Workspace,
    _check_speed,
    _check_start,
    _sample_path,
    validate_settings,
)
from armstereo.capture.scan_plan import ScanPlan
from armstereo.devices import trapezoid_duration
from armstereo.errors import PreflightError
from armstereo.kinematics import ArmModel

JOINT_PATH_STEP_RAD = 0.01  # joint-move samples: at most this change of any joint apart
MAX_DROPPED_SHOWN = 3  # dropped viewpoints named in a refusal


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
class ScanTour:
    """A scan plan checked as one tour: what :func:`armstereo.capture.run.run_capture` runs.

    ``settings`` carries the baseline, settle time, speed caps, margins and workspace;
    ``T_base_flange_right[k]`` is the target of viewpoint ``k``'s baseline move and
    ``q_right[k]`` the joints the path's IK reaches there.
    """

    scan: ScanPlan
    settings: CaptureSettings
    q_start: np.ndarray
    T_base_flange_right: list[np.ndarray]
    q_right: list[np.ndarray]
    legs: list[Leg]
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

    def steps(self) -> list[Step]:
        """The tour as capture steps (module docstring)."""
        views, s = self.scan.views, self.settings
        joints = [leg for leg in self.legs if leg.kind == "joints"]
        baselines = [leg for leg in self.legs if leg.kind == "linear"]
        out = []
        for k, v in enumerate(views):
            out.append(Step("joints", v.q_left, joints[k].duration_s, view=2 * k,
                            say=f"moving to viewpoint {v.index} ({k + 1}/{len(views)})"))
            out.append(Step("linear", self.T_base_flange_right[k], baselines[k].duration_s,
                            view=2 * k + 1,
                            pair=PairStep(k, 2 * k, 2 * k + 1, s.baseline, s.direction_label,
                                          v.index),
                            say=f"baseline move at viewpoint {v.index}"))
        if views:
            out.append(Step("joints", self.q_start, joints[-1].duration_s,
                            say="returning to the start"))
        return out

    def describe(self) -> list[str]:
        """Human-readable lines: the scan plan (kept and dropped viewpoints), the speed caps,
        the estimated duration and every pre-flight check."""
        lim = self.settings.limits
        lines = self.scan.describe()
        lines += [f"  speed caps: {lim.joint_speed:.2f} rad/s, {lim.joint_acceleration:.2f} "
                  f"rad/s^2 (joint moves); {lim.linear_speed:.3f} m/s, "
                  f"{lim.linear_acceleration:.2f} m/s^2 (baseline moves); settle "
                  f"{self.settings.settle_s:.2f} s per view; estimated {self.duration_s:.1f} s",
                  "  tour pre-flight checks:"]
        lines += [f"    [{'ok' if c.ok else 'FAIL'}] {c.name}: {c.detail}" for c in self.checks]
        return lines


def plan_tour(model: ArmModel, scan: ScanPlan, settings: CaptureSettings) -> ScanTour:
    """Check the whole tour of ``scan`` (planned from ``scan.q_start``) with ``settings``
    (baseline = the scan's; its ``pairs`` and ``direction`` are ignored: one pair per
    viewpoint, along camera x).

    Never raises for a failed check (a dry run shows them all); call ``tour.require_ok()``
    before moving. Raises ConfigError for malformed settings.
    """
    settings = replace(settings, baseline=scan.baseline, direction=np.array([1.0, 0.0, 0.0]),
                       direction_label="x", pairs=max(1, len(scan.views)))
    validate_settings(replace(settings, pairs=1))  # a scan may have more pairs than a line
    q_start = np.asarray(scan.q_start, dtype=float)
    box = settings.workspace or Workspace.around(model)
    legs, q_right = _legs(model, scan, settings)
    checks = [_check_speed(settings.limits), _check_start(model, q_start, settings),
              _check_viewpoints(scan)]
    if scan.views:
        checks += _check_legs(model, legs, settings, box)
    duration = sum(leg.duration_s for leg in legs) + 2 * len(scan.views) * settings.settle_s
    right = [model.flange_pose_for_camera(v.T_base_right) for v in scan.views]
    return ScanTour(scan, settings, q_start, right, q_right, legs, checks, duration)


def joint_path(q_from: np.ndarray, q_to: np.ndarray,
               step: float = JOINT_PATH_STEP_RAD) -> np.ndarray:
    """Samples (n, 6) rad of the straight joint-space path moveJ follows from ``q_from`` to
    ``q_to``, at most ``step`` rad of any joint apart, both ends included."""
    q_from, q_to = np.asarray(q_from, float), np.asarray(q_to, float)
    n = max(1, math.ceil(float(np.abs(q_to - q_from).max()) / step))
    s = np.arange(n + 1)[:, None] / n
    return q_from + s * (q_to - q_from)


def _legs(model: ArmModel, scan: ScanPlan, s: CaptureSettings
          ) -> tuple[list[Leg], list[np.ndarray]]:
    """Every move of the tour in order, and the joints reached at each right view."""
    lim = s.limits
    legs, q_right = [], []
    q_prev, where = np.asarray(scan.q_start, float), "start"
    per_move = max(1, math.ceil(s.baseline / s.path_step))
    linear_s = trapezoid_duration(s.baseline, lim.linear_speed, lim.linear_acceleration)
    for v in scan.views:
        legs.append(_joint_leg(q_prev, v.q_left, f"{where} -> viewpoint {v.index}", lim))
        T_left = model.flange_pose_for_camera(v.T_base_left)
        step = v.T_base_right[:3, 3] - v.T_base_left[:3, 3]
        samples = _sample_path(model, v.q_left, T_left, step, per_move, 1)
        label = f"viewpoint {v.index} baseline"
        failed = [err for _, q, err in samples if q is None]
        if failed:
            legs.append(Leg("linear", label, None, linear_s, failed[0]))
            q_end = v.q_right  # the planner's own solution, to go on checking the tour
        else:
            qs = np.array([q for _, q, _ in samples])
            legs.append(Leg("linear", label, qs, linear_s))
            q_end = qs[-1]
        q_right.append(q_end)
        q_prev, where = q_end, f"viewpoint {v.index}"
    if scan.views:
        legs.append(_joint_leg(q_prev, scan.q_start, f"{where} -> start", lim))
    return legs, q_right


def _joint_leg(q_from: np.ndarray, q_to: np.ndarray, label: str, lim) -> Leg:
    travel = float(np.abs(np.asarray(q_to) - q_from).max())
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


def _check_legs(model: ArmModel, legs: list[Leg], s: CaptureSettings,
                box: Workspace) -> list[Check]:
    """IK, joint limits, singularity, continuity, workspace and travel over every move."""
    failed = [leg for leg in legs if leg.samples is None]
    if failed:
        return [Check("IK along the baseline moves", False, f"{failed[0].label}: "
                      f"{failed[0].error}")]
    baselines = [leg for leg in legs if leg.kind == "linear"]
    checks = [Check("IK along the baseline moves", True,
                    f"{sum(len(leg.samples) for leg in baselines)} samples every "
                    f"{s.path_step * 1000:.0f} mm on {len(baselines)} baseline moves; joint "
                    f"moves sampled every {JOINT_PATH_STEP_RAD} rad")]
    margin, margin_at = min((_margin(model, leg.samples), leg.label) for leg in legs)
    checks.append(Check("joint limits", margin >= s.joint_margin,
                        f"smallest margin {margin:.3f} rad on {margin_at} (needs >= "
                        f"{s.joint_margin:.3f})"))
    sigma, sigma_at = min((min(model.sigma_min(q) for q in leg.samples), leg.label)
                           for leg in legs)
    checks.append(Check("singularity", sigma >= s.min_sigma,
                        f"smallest Jacobian singular value {sigma:.4f} on {sigma_at} (needs >= "
                        f"{s.min_sigma})"))
    jump, jump_at = max((float(np.abs(np.diff(leg.samples, axis=0)).max()), leg.label)
                         for leg in baselines)
    checks.append(Check("path continuity", jump <= MAX_SAMPLE_JUMP_RAD,
                        f"largest joint change between samples {jump:.3f} rad on {jump_at} "
                        f"(needs <= {MAX_SAMPLE_JUMP_RAD})"))
    checks.append(_check_workspace(model, legs, box))
    travel, travel_at = max((float(np.abs(leg.samples[-1] - leg.samples[0]).max()), leg.label)
                             for leg in baselines)
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
