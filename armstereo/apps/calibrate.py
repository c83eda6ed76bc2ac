"""``armstereo calibrate``: plan a calibration session from the start view, record it, compute.

The steps the command runs, each usable alone:

1. :func:`plan_session`: grab one image at the start pose, find the board (its pose with the
   mount's nominal intrinsics), plan N diverse views around it
   (:func:`armstereo.calibration.plan_calibration_views`), order them for a short tour and
   check every joint move as a scan checks its joint moves
   (:mod:`armstereo.capture.view_tour`).
2. :func:`armstereo.capture.session.capture_to_file` runs that tour as any capture: move,
   settle, grab, read the actual joints, record (crash-safe; the arm stops on any error).
3. :func:`finish`: calibrate the recorded session exactly as ``calibrate --from`` does
   (:func:`armstereo.calibration.session.calibrate_recording`), so the live result and an
   offline recomputation of its recording are the same computation on the same data, and
   write the mount file.

On the mock, :func:`mock_camera_values` lays the board on the mock table; the camera is the
mock cell's (the one ``capture`` meets on the same profile and seed). All poses are in the
controller's ``base`` frame.
"""

from __future__ import annotations

import re
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from armstereo.calibration.board import Board
from armstereo.calibration.calibrate import Calibration, CalibrationOptions
from armstereo.calibration.checks import MIN_VIEWS
from armstereo.calibration.coverage import coverage_views
from armstereo.calibration.session import calibrate_recording
from armstereo.calibration.views import (
    CalibrationViewPlan,
    ViewPlanSettings,
    board_in_start_view,
    plan_calibration_views,
)
from armstereo.capture.plan import CaptureSettings
from armstereo.capture.scan_plan import order_tour
from armstereo.capture.view_tour import ViewTour, plan_view_tour, tour_settings
from armstereo.devices import Camera
from armstereo.errors import ArmstereoError
from armstereo.io.files import write_text_atomic
from armstereo.mount import CameraMount
from armstereo.robot.arm_model import ArmModel


@dataclass
class SessionPlan:
    """A planned calibration session: the start image, the board seen in it, the views (in
    tour order; view 0 is the start pose) and the checked tour."""

    start_image: np.ndarray
    T_camera_board_start: np.ndarray
    views: CalibrationViewPlan
    tour: ViewTour

    @property
    def ok(self) -> bool:
        return self.tour.ok

    def describe(self) -> list[str]:
        d = self.views.views[0].distance_m
        lines = [f"board found in the start image, its centre {d:.3f} m from the camera"]
        return lines + self.views.describe() + self.tour.describe()


def plan_session(model: ArmModel, camera: Camera, q_start: np.ndarray, board: Board, *,
                 views: ViewPlanSettings | None = None,
                 tour: CaptureSettings | None = None, corner_views: int = 0) -> SessionPlan:
    """Grab the start image, find the board and plan and check the session (moves nothing).

    ``model`` carries the kinematics the session will use (calibrated where read) and the
    nominal mount; ``tour`` the settle time, speed caps and workspace
    (:func:`armstereo.capture.view_tour.tour_settings`). Raises CalibrationInputError (exit 2)
    when the board is not (well) visible in the start image and PreflightError (exit 3) when
    too few views can be reached; a failed tour check is left in the plan
    (``plan.tour.require_ok()``). ``corner_views`` of the views (at most as many as leave
    MIN_VIEWS orbit views) put the board into the image corners instead of its middle
    (:mod:`armstereo.calibration.coverage`: the lens's distortion and vignetting are largest
    there); an orbit view stays where a corner view cannot be reached.
    """
    views = views or ViewPlanSettings()
    image = camera.grab().image
    T_cb = board_in_start_view(image, board, camera.intrinsics)
    plan = plan_calibration_views(model, q_start, board, T_camera_board_start=T_cb,
                                  settings=views)
    plan = _with_corner_views(model, q_start, plan, board, views,
                              min(corner_views, views.n_views - MIN_VIEWS))
    ordered = _tour_order(np.asarray(q_start, float), plan)
    q_views = [v.q for v in ordered.views]
    return SessionPlan(image, T_cb, ordered, plan_view_tour(model, q_start, q_views,
                                                                  tour or tour_settings()))


def _with_corner_views(model: ArmModel, q_start: np.ndarray, plan: CalibrationViewPlan,
                       board: Board, settings: ViewPlanSettings,
                       n: int) -> CalibrationViewPlan:
    """The plan with its last ``n`` orbit views replaced by corner views (those that pass)."""
    if n <= 0:
        return plan
    corners, skipped = coverage_views(model, q_start, plan, board, n, settings)
    kept = plan.views[:len(plan.views) - len(corners)]
    return CalibrationViewPlan(kept + corners, plan.T_base_board, plan.diversity,
                               plan.skipped + skipped)


def _tour_order(q_start: np.ndarray, plan: CalibrationViewPlan) -> CalibrationViewPlan:
    """The plan with views 1.. reordered for a short tour (view 0, the start, stays first).
    The calibration uses every pair of views, so their order does not change the result."""
    rest = plan.views[1:]
    q = [v.q for v in rest]
    order, _ = order_tour(q_start, q, q)
    return CalibrationViewPlan([plan.views[0], *(rest[i] for i in order)], plan.T_base_board,
                               plan.diversity, plan.skipped)


def finish(recording: Path, out: Path, board: Board) -> Calibration:
    """Calibrate the recorded session and write the mount file ``out`` (atomically).

    An error of the computation (bad views) keeps its exit code and says that the recording
    is kept and how to redo the computation from it.
    """
    try:
        cal = calibrate_recording(recording, board=board, options=calibration_options(out))
    except ArmstereoError as err:
        err.args = (f"{err}; the recording {recording} is kept (redo the computation with "
                    f"armstereo calibrate --from {recording} --out {out})",)
        raise
    write_text_atomic(out, cal.mount_toml)
    return cal


def calibration_options(out: Path) -> CalibrationOptions:
    """The default computation, with the mount named after its file (``my_camera.toml`` ->
    ``my_camera``; characters a mount name cannot hold become ``_``)."""
    name = re.sub(r"[^A-Za-z0-9_.\-]", "_", Path(out).stem) or "calibrated_camera"
    return CalibrationOptions(mount_name=name)


def mock_camera_values(board: Board, nominal: CameraMount | None = None,
                       seed: int | None = None) -> dict:
    """Mock camera config values for a calibration: the board on the table. The camera is the
    mock cell's own (``drivers.mock.cell``: on the realistic profile the bundled mount moved
    by a CAD guess's error, with lens distortion and vignetting), the same camera ``capture``
    meets on that cell, so the mount file the calibration writes is right for it.
    ``nominal`` and ``seed`` are accepted for older callers and not used."""
    return {"board": board}


@dataclass(frozen=True, kw_only=True)
class MockCalibration:
    """A calibration session on the mock cell, as ``armstereo calibrate --camera mock`` runs
    it: the views planned from the ``table`` start pose, recorded and calibrated."""

    board: str = "chessboard:17x12:0.016"
    views: int = 10
    corner_views: int = 4
    robot: str = "ur5e"
    profile: Any = "realistic"
    seed: int = 0


def calibrate_mock_cell(out: Path, recording: Path, settings: MockCalibration,
                        progress: Callable[[str], None] | None = None) -> Calibration:
    """Plan, record (``recording``) and calibrate a session on the mock cell named by
    ``settings.profile`` and ``settings.seed``, starting from the bundled mount file, and
    write the mount file ``out``. The same steps as the live command, without a prompt (the
    mock moves nothing real)."""
    from armstereo import backends
    from armstereo.calibration.board import parse_board
    from armstereo.calibration.session import calibration_metadata
    from armstereo.capture.run import model_metadata
    from armstereo.capture.session import capture_to_file
    from armstereo.robot.model_file import load_arm_model
    from armstereo.robot.source import choose_kinematics

    board = parse_board(settings.board)
    model = load_arm_model(settings.robot, mount=CameraMount.load(None))
    arm_cfg = backends.arm_config("mock", seed=settings.seed, profile=settings.profile)
    cam_cfg = backends.camera_config("mock", seed=settings.seed, profile=settings.profile,
                                     **mock_camera_values(board))
    with backends.build_arm("mock", arm_cfg, model) as arm:
        kinematics = choose_kinematics(model, arm, live=False)
        model = kinematics.model
        with backends.build_camera("mock", cam_cfg, model, arm) as camera:
            plan = plan_session(model, camera, arm.joint_positions(), board,
                                views=ViewPlanSettings(n_views=settings.views),
                                corner_views=settings.corner_views)
            plan.tour.require_ok()
            metadata = {**model_metadata(model), **kinematics.metadata(), "arm": "mock",
                        "camera": "mock", "mock_profile": arm_cfg.profile.name,
                        **calibration_metadata(board, settings.views)}
            capture_to_file(arm, camera, model, plan.tour, recording, metadata,
                            progress=progress)
    return finish(recording, out, board)
