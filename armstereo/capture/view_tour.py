"""A tour of views reached by joint moves, checked before anything moves, run by capture.

A calibration's views tilt and roll the camera by tens of degrees, so they are not one straight
line: the arm reaches each view by a joint move (UR moveJ), shoots it, and returns to the start
by a joint move at the end. Every move is checked exactly as a scan tour checks its joint moves
(:mod:`armstereo.capture.tour`: :func:`~armstereo.capture.tour.joint_leg` samples the straight
joint-space path moveJ follows, :func:`~armstereo.capture.tour.check_legs` checks joint limits
with margin, singularity and the workspace box for flange and camera on every sample), plus
capture's speed caps and start pose (:mod:`armstereo.capture.plan`).

Speed: a joint move's tool speed is the joints' speed times the lever arm, which for a UR arm
reaching out is up to about 0.8 m per radian. The tour therefore moves its joints at the
largest speed (and acceleration) that keeps both flange and camera under the linear caps on
every move, and never above the joint caps; the ``tool speed`` check reports it. The plan is
a :class:`~armstereo.capture.run.CapturePlanLike`: ``capture_to_file`` records it (view 0 is
shot where the arm stands). All poses are in the controller's ``base`` frame.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from armstereo.capture.plan import (
    CaptureSettings,
    Check,
    Checked,
    Step,
    Workspace,
    check_speed,
    check_start,
    validate_settings,
)
from armstereo.capture.tour import Leg, check_legs, joint_leg, joint_path
from armstereo.devices import MotionLimits
from armstereo.robot.arm_model import ArmModel

SAME_JOINTS_RAD = 1e-9  # a move shorter than this is not made
# CaptureSettings fields a view tour does not use (it records no pairs).
_NO_BASELINE_M = 0.01
_NO_DIRECTION = np.array([1.0, 0.0, 0.0])


def tour_settings(*, settle_s: float = 0.5, limits: MotionLimits | None = None,
                  workspace: Workspace | None = None, joint_margin: float = 0.05,
                  min_sigma: float = 0.02) -> CaptureSettings:
    """CaptureSettings for a view tour: settle time (s), speed caps, workspace box and the
    margins; baseline, direction and pairs are not used (a view tour records no pairs)."""
    return CaptureSettings(baseline=_NO_BASELINE_M, direction=_NO_DIRECTION, settle_s=settle_s,
                           limits=limits or MotionLimits(), workspace=workspace,
                           joint_margin=joint_margin, min_sigma=min_sigma)


@dataclass
class ViewTour(Checked):
    """The checked tour. ``settings.limits`` holds the joint speed and acceleration the tour
    moves at (see the module doc); ``requested`` the caps asked for; ``legs[k]`` is the move
    into view ``k`` (None for view 0 when the arm already stands there), the last one the
    way back; ``lever_m`` the largest flange or camera displacement per radian of the leading
    joint on any move."""

    settings: CaptureSettings
    requested: MotionLimits
    q_start: np.ndarray
    q_views: list[np.ndarray]
    legs: list[Leg | None]
    checks: list[Check]
    lever_m: float
    duration_s: float

    def steps(self) -> list[Step]:
        """Per view: a joint move (none for a view where the arm stands), a shot; then the
        joint move back to the start."""
        n = len(self.q_views)
        out = []
        for k, (q, leg) in enumerate(zip(self.q_views, self.legs, strict=False)):
            if leg is None:
                out.append(Step("none", None, 0.0, view=k))
            else:
                out.append(Step("joints", q, leg.duration_s, view=k,
                                say=f"moving to view {k} of {n}"))
        home = self.legs[-1]
        if home is not None:
            out.append(Step("joints", self.q_start, home.duration_s,
                            say="returning to the start"))
        return out

    def describe(self) -> list[str]:
        """Human-readable lines: the moves and every check."""
        s, lim = self.settings, self.settings.limits
        lines = [f"tour: {len(self.q_views)} views by joint moves, then back to the start; "
                 f"estimated {self.duration_s:.1f} s",
                 f"  joints at {lim.joint_speed:.3f} rad/s, {lim.joint_acceleration:.3f} "
                 f"rad/s^2: flange and camera at most {lim.joint_speed * self.lever_m:.3f} m/s "
                 f"(cap {self.requested.linear_speed:g} m/s); settle {s.settle_s:.2f} s per "
                 "view"]
        for leg in self.legs:
            if leg is not None:
                travel = float(np.abs(leg.samples[-1] - leg.samples[0]).max())
                lines.append(f"    {leg.label}: largest joint {travel:.3f} rad, "
                             f"{leg.duration_s:.1f} s")
        lines.append("  pre-flight checks:")
        lines += [f"    [{'ok' if c.ok else 'FAIL'}] {c.name}: {c.detail}" for c in self.checks]
        return lines


def plan_view_tour(model: ArmModel, q_start: np.ndarray, q_views: list[np.ndarray],
                   settings: CaptureSettings) -> ViewTour:
    """Check the tour from ``q_start`` through ``q_views`` (rad, in order) and back.

    ``settings`` as from :func:`tour_settings`. Never raises for a failed check (so --dry-run
    can show them all); call ``tour.require_ok()`` before moving. Raises ConfigError for
    malformed settings.
    """
    validate_settings(settings)
    q_start = np.asarray(q_start, dtype=float).reshape(6)
    views = [np.asarray(q, dtype=float).reshape(6) for q in q_views]
    requested = settings.limits
    stops = [q_start, *views, q_start]
    moves = [(a, b) for a, b in zip(stops[:-1], stops[1:], strict=True)]
    lever = max((_lever(model, a, b) for a, b in moves), default=0.0)
    settings = replace(settings, limits=_tour_limits(requested, lever))
    labels = ["start", *(f"view {k}" for k in range(len(views))), "start"]
    legs: list[Leg | None] = []
    for k, (a, b) in enumerate(moves):
        same = float(np.abs(b - a).max()) < SAME_JOINTS_RAD
        legs.append(None if same else joint_leg(a, b, f"{labels[k]} -> {labels[k + 1]}",
                                                settings))
    checks = [check_speed(requested), check_start(model, q_start, settings)]
    made = [leg for leg in legs if leg is not None]
    if made:
        checks += check_legs(model, made, settings, settings.workspace
                             or Workspace.around(model))
    checks.append(_check_tool_speed(settings.limits, lever, requested))
    duration = sum(leg.duration_s for leg in made) + len(views) * settings.settle_s
    return ViewTour(settings, requested, q_start, views, legs, checks, lever, duration)


def _lever(model: ArmModel, a: np.ndarray, b: np.ndarray) -> float:
    """Largest displacement (m) of flange or camera per radian of the leading joint along the
    joint move from ``a`` to ``b`` (0 for no move)."""
    path = joint_path(a, b)
    travel = float(np.abs(b - a).max())
    if travel < SAME_JOINTS_RAD:
        return 0.0
    T_fc = model.mount.T_flange_camera
    pts = np.array([[T[:3, 3], (T @ T_fc)[:3, 3]] for T in map(model.flange_pose, path)])
    step = travel / (len(path) - 1)
    return float(np.linalg.norm(np.diff(pts, axis=0), axis=2).max() / step)


def _tour_limits(requested: MotionLimits, lever: float) -> MotionLimits:
    """The joint caps of ``requested``, lowered so that ``lever`` m/rad moves no point of
    flange or camera faster than its linear caps."""
    if lever <= 0 or not (requested.linear_speed > 0 and requested.linear_acceleration > 0):
        return requested  # nothing moves, or the speed-caps check refuses the tour anyway
    return replace(requested,
                   joint_speed=min(requested.joint_speed, requested.linear_speed / lever),
                   joint_acceleration=min(requested.joint_acceleration,
                                          requested.linear_acceleration / lever))


def _check_tool_speed(used: MotionLimits, lever: float, requested: MotionLimits) -> Check:
    peak = used.joint_speed * lever
    ok = peak <= requested.linear_speed * (1 + 1e-9)
    return Check("tool speed", ok, f"joints at {used.joint_speed:.3f} rad/s move flange and "
                 f"camera at most {peak:.3f} m/s (cap {requested.linear_speed:g} m/s; "
                 f"lever {lever:.3f} m/rad)")
