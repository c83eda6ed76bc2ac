"""A multi-view scan from start to end: connect, plan the viewpoints, check the whole tour,
confirm, capture every viewpoint's pair into one recording.

This is what ``armstereo scan`` runs, and what the tests, the fusion benchmark and
``armstereo demo --scan`` record scans with. Motion goes through the capture machinery
(:func:`armstereo.capture.session.capture_to_file`, :func:`armstereo.capture.run.run_capture`):
the same pre-flight rule (nothing moves unless every check of the tour passes), the same
stop-on-error (any error ends with the arm told to stop), the same crash-safe recording (a
fault keeps every complete pair) and the same kinematics choice and metadata as ``capture``.

``--views auto:N`` chooses up to N viewpoints while scanning (greedy next-best view,
:mod:`armstereo.fusion.nbv`; every move is still checked before the arm makes it).

Recording metadata (besides capture's): ``kind`` = ``scan``, ``views`` (the layout as asked),
``target_m`` (``x,y,z``, base frame), ``radius_m``, ``elevation_deg``, ``baseline_m``,
``direction`` = ``x``, ``pairs`` (viewpoints planned; for ``auto:N``, N) and
``scan_viewpoints`` (JSON list in tour order, for ``auto:N`` the candidates: ``viewpoint``,
``azimuth_deg``, ``elevation_deg``, ``roll_deg``, ``T_base_camera`` row-major 4x4). Each pair
event carries its ``viewpoint``.
"""

from __future__ import annotations

import json
import logging
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from armstereo import backends
from armstereo.capture.plan import CaptureSettings, Workspace
from armstereo.capture.run import CaptureResult, model_metadata
from armstereo.capture.scan_plan import (
    DEFAULT_BASELINE_M,
    DEFAULT_ELEVATION_DEG,
    DEFAULT_RADIUS_M,
    ScanSettings,
    plan_scan,
)
from armstereo.capture.session import capture_to_file, confirm_live_motion
from armstereo.capture.tour import ScanTour, plan_tour
from armstereo.devices import MotionLimits
from armstereo.robot.arm_model import ArmModel
from armstereo.robot.source import choose_kinematics

if TYPE_CHECKING:
    from armstereo.fusion.nbv import AutoTour

log = logging.getLogger(__name__)

METADATA_VIEWPOINTS = "scan_viewpoints"
DEFAULT_SETTLE_S = 0.5


@dataclass(frozen=True)
class ScanRequest:
    """What to scan: ``target`` (base frame, m), the ``views`` layout (``ring:N``,
    ``sphere:N``, ``grid:RxC``), ``radius`` m, ``elevation_deg``, ``baseline`` m; how: settle
    time s, speed caps, workspace box (None: the arm's reach), image compression."""

    target: tuple[float, float, float]
    views: str = "ring:12"
    radius: float = DEFAULT_RADIUS_M
    elevation_deg: float = DEFAULT_ELEVATION_DEG
    baseline: float = DEFAULT_BASELINE_M
    settle_s: float = DEFAULT_SETTLE_S
    limits: MotionLimits = field(default_factory=MotionLimits)
    workspace: Workspace | None = None
    image_format: str = "png"

    def capture_settings(self) -> CaptureSettings:
        return CaptureSettings(baseline=self.baseline, direction=np.array([1.0, 0.0, 0.0]),
                               settle_s=self.settle_s, limits=self.limits,
                               workspace=self.workspace)


@dataclass(frozen=True)
class ScanOutcome:
    """What :func:`record_scan` did: the checked tour, what was recorded (None for a dry run),
    the recording's path and where the kinematics came from."""

    tour: ScanTour | AutoTour
    result: CaptureResult | None
    out: Path
    kinematics_source: str


def plan_scan_tour(model: ArmModel, q_start: np.ndarray, request: ScanRequest
                   ) -> ScanTour | AutoTour:
    """Viewpoints of ``request`` from joints ``q_start`` (rad), checked as one tour; for
    ``auto:N`` the candidates, each checked (:mod:`armstereo.fusion.nbv`)."""
    from armstereo.fusion.nbv import candidate_layout, parse_auto

    settings = request.capture_settings()
    budget = parse_auto(request.views)
    scan = plan_scan(model, q_start, request.target,
                     views=request.views if budget is None else candidate_layout(budget),
                     radius=request.radius, elevation_deg=request.elevation_deg,
                     baseline=request.baseline,
                     settings=ScanSettings(joint_margin=settings.joint_margin,
                                           min_sigma=settings.min_sigma,
                                           path_step=settings.path_step,
                                           workspace=request.workspace))
    if budget is None:
        return plan_tour(model, scan, settings)
    from armstereo.fusion.nbv import plan_auto

    return plan_auto(model, scan, settings, budget)


def record_scan(out: str | Path, request: ScanRequest, model: ArmModel, *, arm: str = "mock",
                arm_config: Any = None, camera: str = "mock", camera_config: Any = None,
                dry_run: bool = False, yes: bool = False,
                ask: Callable[[], str | None] = lambda: None,
                show: Callable[[ScanTour], None] | None = None,
                metadata: Mapping[str, str] | None = None,
                progress: Callable[[str], None] | None = log.info) -> ScanOutcome:
    """Connect ``arm``, plan and check the tour, then (unless ``dry_run``) capture it into the
    recording ``out``.

    ``model`` is the arm model given (``--robot``, ``--mount``); the arm's own calibrated
    kinematics replace it where it has them (:func:`choose_kinematics`). ``show`` sees the
    checked tour before it is enforced (to print it). A real arm needs ``yes`` or ``ask`` to
    return the confirmation word (:func:`confirm_live_motion`). ``metadata`` adds recording
    keys (e.g. :func:`backend_metadata`). Raises PreflightError (nothing moved) when a check of
    the tour fails, UserAbort when not confirmed, HardwareError / RecordingError from the
    capture (the arm stopped, every complete pair kept).
    """
    out = Path(out)
    arm_config = arm_config if arm_config is not None else backends.arm_config(arm)
    camera_config = camera_config if camera_config is not None else backends.camera_config(
        camera)
    live = arm != "mock"
    with backends.build_arm(arm, arm_config, model) as device:
        device.require_ok()
        kinematics = choose_kinematics(model, device, live=live)
        model = kinematics.model  # plans moves and computes poses with the arm's own table
        tour = plan_scan_tour(model, device.joint_positions(), request)
        if show is not None:
            show(tour)
        tour.require_ok()
        if dry_run:
            return ScanOutcome(tour, None, out, kinematics.source)
        confirm_live_motion(live=live, yes=yes, ask=ask)
        with backends.build_camera(camera, camera_config, model, device) as cam:
            meta = {**model_metadata(model), **(metadata or {}), **scan_metadata(tour, request),
                    **kinematics.metadata()}
            observer = (tour.observer(cam.intrinsics, model.mount.vignetting)
                        if hasattr(tour, "observer") else None)
            result = capture_to_file(device, cam, model, tour, out, meta,
                                     image_format=request.image_format, progress=progress,
                                     on_view=observer)
    return ScanOutcome(tour, result, out, kinematics.source)


def scan_metadata(tour: ScanTour, request: ScanRequest) -> dict[str, str]:
    """The scan's recording metadata keys (module docstring)."""
    scan = tour.scan
    viewpoints = [{"viewpoint": v.index, "azimuth_deg": round(v.azimuth_deg, 6),
                   "elevation_deg": round(v.elevation_deg, 6), "roll_deg": v.roll_deg,
                   "T_base_camera": np.round(v.T_base_camera, 9).reshape(-1).tolist()}
                  for v in scan.views]
    lim = request.limits
    return {"kind": "scan", "views": request.views,
            "target_m": ",".join(f"{v:.6g}" for v in scan.target),
            "radius_m": repr(scan.radius), "elevation_deg": repr(scan.elevation_deg),
            "baseline_m": repr(scan.baseline), "direction": "x",
            "pairs": str(getattr(tour, "budget", len(scan.views))),
            "speed_m_s": repr(lim.linear_speed), "acceleration_m_s2": repr(lim.linear_acceleration),
            "joint_speed_rad_s": repr(lim.joint_speed),
            "joint_acceleration_rad_s2": repr(lim.joint_acceleration),
            "settle_s": repr(request.settle_s), METADATA_VIEWPOINTS: json.dumps(viewpoints)}


def backend_metadata(arm: str, arm_config: Any, camera: str, camera_config: Any
                     ) -> dict[str, str]:
    """Recording metadata naming the backends and their simulated errors (as capture records
    them): ``arm``, ``host``, ``camera``, ``joint_noise_rad``, ``camera_noise``, ``faults``,
    ``mock_profile``."""
    profile = (getattr(getattr(arm_config, "profile", None), "name", "")
               or getattr(getattr(camera_config, "profile", None), "name", ""))
    return {"arm": arm, "host": getattr(arm_config, "host", None) or "", "camera": camera,
            "joint_noise_rad": repr(getattr(arm_config, "joint_noise", 0.0)),
            "camera_noise": repr(getattr(camera_config, "noise", 0.0)),
            "faults": ",".join(getattr(arm_config, "faults", ())
                               or getattr(camera_config, "faults", ())),
            "mock_profile": profile}
