"""Plan calibration views: diverse arm poses that keep the board in view. Moves nothing.

From a start pose whose camera sees the board, every other view orbits the board's centre:
the optical axis is tilted about an axis perpendicular to it (the tilt's azimuth goes round by
the golden angle, so consecutive views tilt about different, non-parallel axes), the camera
rolls about its optical axis and its distance to the board changes. The camera keeps looking
at the board's centre. Each view is checked with the arm model: IK on the start pose's branch,
joint limits with a margin, distance from singularities, height above the base plane and the
whole board inside the image (with the mount's nominal hand-eye and intrinsics, which only
need to be roughly right). A view that fails is retried with smaller tilt and roll, then
skipped. All poses are in the controller's ``base`` frame.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import cv2
import numpy as np

from armstereo.calibration.board import Board, detect_board
from armstereo.calibration.checks import MIN_CORNER_SPACING_PX, MIN_VIEWS, CalibrationInputError
from armstereo.calibration.handeye import MotionDiversity, motion_diversity, motion_pairs
from armstereo.calibration.intrinsics import board_pose
from armstereo.calibration.poses import as_rigid, rotmat
from armstereo.camera_model import Intrinsics
from armstereo.errors import ConfigError, IKError, PreflightError
from armstereo.robot.arm_model import ArmModel
from armstereo.transforms import invert, make_T

GOLDEN_ANGLE_DEG = 180.0 * (3.0 - math.sqrt(5.0))  # ~137.5: azimuths never line up
MAX_VIEWS = 60
DEFAULT_START_DISTANCE_M = 0.4  # assumed board distance when the start view was not measured
SHRINK = (1.0, 0.6, 0.35)  # tilt/roll scales tried for a candidate before skipping it


@dataclass(frozen=True)
class ViewPlanSettings:
    """Shape of the view set. Angles in degrees, lengths in metres."""

    n_views: int = 15
    # Larger tilts pin the principal point (and so the hand-eye rotation) down better; 35 deg
    # keeps a board that fills half the image in view on a UR5e (measured on simulations).
    max_tilt_deg: float = 35.0  # of the optical axis about the board centre
    max_roll_deg: float = 60.0  # about the optical axis
    distance_factors: tuple[float, ...] = (1.0, 0.85, 1.15)  # times the start distance
    joint_margin: float = 0.05  # rad, as capture's default
    min_sigma: float = 0.02  # smallest Jacobian singular value allowed, as capture's default
    image_margin_px: float = 15.0  # board outline this far inside the image
    min_height_m: float = 0.05  # flange and camera above the base plane (z in base)
    max_candidates_factor: int = 4  # candidates tried per wanted view


@dataclass(frozen=True)
class PlannedView:
    """One planned view: flange and camera pose (base frame), joints (rad), and how it was made."""

    T_base_flange: np.ndarray
    T_base_camera: np.ndarray
    q: np.ndarray
    tilt_deg: float
    azimuth_deg: float
    roll_deg: float
    distance_m: float


@dataclass
class CalibrationViewPlan:
    """The views (view 0 is the start pose), the board pose assumed, and what was skipped."""

    views: list[PlannedView]
    T_base_board: np.ndarray  # assumed (from the start view, or a guess)
    diversity: MotionDiversity
    skipped: list[str] = field(default_factory=list)

    @property
    def q_views(self) -> list[np.ndarray]:
        return [v.q for v in self.views]

    def describe(self) -> list[str]:
        """Human-readable lines for --dry-run."""
        d = self.diversity
        lines = [f"calibration plan: {len(self.views)} views; rotations up to "
                 f"{d.max_rotation_deg:.0f} deg between views, axes spread "
                 f"{d.axis_spread_deg:.0f} deg, {d.usable_pairs} of {d.pairs} pairs usable"]
        for k, v in enumerate(self.views):
            p = v.T_base_camera[:3, 3]
            lines.append(f"  view {k:2d}: tilt {v.tilt_deg:4.1f} deg (azimuth "
                         f"{v.azimuth_deg:5.1f}), roll {v.roll_deg:+5.1f} deg, distance "
                         f"{v.distance_m:.3f} m, camera ({p[0]:+.3f}, {p[1]:+.3f}, "
                         f"{p[2]:+.3f}) q " + " ".join(f"{x:+.3f}" for x in v.q))
        lines += [f"  skipped: {s}" for s in self.skipped]
        return lines


def plan_calibration_views(model: ArmModel, q_start: np.ndarray, board: Board, *,
                           T_camera_board_start: np.ndarray | None = None,
                           settings: ViewPlanSettings = ViewPlanSettings()
                           ) -> CalibrationViewPlan:
    """Plan ``settings.n_views`` views around the board seen from ``q_start``.

    ``T_camera_board_start`` is the board's pose in the start view (e.g. PnP on the first
    image with the nominal intrinsics); without it the board is assumed centred on the optical
    axis, facing the camera, DEFAULT_START_DISTANCE_M away. ``model`` needs a mount (its
    nominal hand-eye and intrinsics). Raises ConfigError for bad settings and PreflightError
    when fewer than ``n_views`` views pass every check (the message says what to change).
    """
    _validate(settings)
    if model.mount is None:
        raise ConfigError("view planning needs the arm model's camera mount (nominal hand-eye "
                          "and intrinsics)")
    q_start = np.asarray(q_start, dtype=float)
    T0_cam = model.camera_pose(q_start)
    if T_camera_board_start is None:
        T_cb = make_T(np.eye(3), [0.0, 0.0, DEFAULT_START_DISTANCE_M]) @ make_T(
            np.eye(3), -board.center)
    else:
        T_cb = as_rigid(T_camera_board_start, "T_camera_board_start")
    T_base_board = T0_cam @ T_cb
    target = (T_base_board @ np.append(board.center, 1.0))[:3]
    d0 = float(np.linalg.norm(target - T0_cam[:3, 3]))
    problem = _check_view(model, q_start, T0_cam, T_base_board, board, settings)
    if problem:
        raise PreflightError(f"the start pose cannot be a calibration view: {problem}")
    views = [PlannedView(model.flange_pose(q_start), T0_cam, q_start, 0.0, 0.0, 0.0, d0)]
    skipped: list[str] = []
    n_candidates = settings.n_views * settings.max_candidates_factor
    for k in range(1, n_candidates):
        if len(views) == settings.n_views:
            break
        view, why = _candidate(model, q_start, T0_cam, target, d0, k, T_base_board, board,
                               settings)
        if view is None:
            skipped.append(f"candidate {k}: {why}")
        else:
            views.append(view)
    if len(views) < settings.n_views:
        reasons = "; ".join(skipped[:3])
        raise PreflightError(
            f"only {len(views)} of {settings.n_views} calibration views pass the checks "
            f"({reasons}); move the start pose away from joint limits and singularities, "
            "closer to the board's centre, or lower the tilt")
    flanges = [v.T_base_flange for v in views]
    cams = [invert(v.T_base_camera) @ T_base_board for v in views]
    div = motion_diversity(motion_pairs(flanges, cams))
    return CalibrationViewPlan(views, T_base_board, div, skipped)


def board_in_start_view(image: np.ndarray, board: Board, intrinsics: Intrinsics) -> np.ndarray:
    """T_camera_board of the board in the start image (nominal intrinsics are good enough for
    planning); CalibrationInputError saying what to do when the board is not (well) visible."""
    det = detect_board(image, board)
    if det is None:
        raise CalibrationInputError(
            f"the {board.kind} is not found in the start image; jog the arm until the camera "
            "sees the whole board from 0.3-0.5 m, evenly lit, and check --board")
    if det.spacing_px < MIN_CORNER_SPACING_PX:
        raise CalibrationInputError(
            f"the board is too small in the start image (corners {det.spacing_px:.1f} px "
            f"apart, need >= {MIN_CORNER_SPACING_PX:g}); start closer or use larger squares")
    return board_pose(det, intrinsics)


def _validate(s: ViewPlanSettings) -> None:
    if not MIN_VIEWS <= s.n_views <= MAX_VIEWS:
        raise ConfigError(f"--views must be in {MIN_VIEWS}..{MAX_VIEWS}, got {s.n_views}")
    if not 5.0 <= s.max_tilt_deg <= 60.0:
        raise ConfigError(f"tilt must be in 5..60 deg, got {s.max_tilt_deg}")
    if not 0.0 <= s.max_roll_deg <= 90.0:
        raise ConfigError(f"roll must be in 0..90 deg, got {s.max_roll_deg}")
    if not s.distance_factors or min(s.distance_factors) <= 0.2 or max(s.distance_factors) > 3:
        raise ConfigError(f"distance factors must be in (0.2, 3], got {s.distance_factors}")


def _candidate(model: ArmModel, q_start: np.ndarray, T0_cam: np.ndarray, target: np.ndarray,
               d0: float, k: int, T_base_board: np.ndarray, board: Board,
               s: ViewPlanSettings) -> tuple[PlannedView | None, str]:
    """The k-th orbit pose (k >= 1), shrunk until it passes the checks, or (None, reason)."""
    azimuth = (k * GOLDEN_ANGLE_DEG) % 360.0
    tilt = s.max_tilt_deg * (0.55 + 0.45 * ((k * 0.618034) % 1.0))
    roll = s.max_roll_deg * (2.0 * ((k * 0.754878 + 0.5) % 1.0) - 1.0)
    dist = d0 * s.distance_factors[k % len(s.distance_factors)]
    why = ""
    for scale in SHRINK:
        T_cam = _orbit_pose(T0_cam, target, dist, tilt * scale, azimuth, roll * scale)
        T_flange = model.flange_pose_for_camera(T_cam)
        try:
            q = model.ik(T_flange, q_start, margin=s.joint_margin)
        except IKError as err:
            why = f"IK: {err}"
            continue
        why = _check_view(model, q, T_cam, T_base_board, board, s)
        if not why:
            return PlannedView(model.flange_pose(q), T_cam, q, tilt * scale, azimuth,
                               roll * scale, dist), ""
    return None, why


def _orbit_pose(T0_cam: np.ndarray, target: np.ndarray, dist: float, tilt_deg: float,
                azimuth_deg: float, roll_deg: float) -> np.ndarray:
    """Camera pose looking at ``target`` from ``dist``: the start orientation turned by
    ``tilt`` about the start camera's axis (cos az, sin az, 0), then rolled about its own z."""
    a = math.radians(azimuth_deg)
    axis = np.array([math.cos(a), math.sin(a), 0.0])
    R = T0_cam[:3, :3] @ rotmat(axis * math.radians(tilt_deg)) @ rotmat(
        [0.0, 0.0, math.radians(roll_deg)])
    return make_T(R, target - dist * R[:, 2])


def check_view(model: ArmModel, q: np.ndarray, T_cam: np.ndarray, T_base_board: np.ndarray,
               board: Board, settings: ViewPlanSettings) -> str:
    """Empty string if a view at joints ``q`` (camera ``T_cam``, base frame) passes the
    planner's checks; otherwise the first failed check, with its numbers."""
    return _check_view(model, q, T_cam, T_base_board, board, settings)


def _check_view(model: ArmModel, q: np.ndarray, T_cam: np.ndarray, T_base_board: np.ndarray,
                board: Board, s: ViewPlanSettings) -> str:
    """Empty string if the view passes; otherwise the first failed check, with its numbers."""
    if not model.within_limits(q, s.joint_margin):
        return f"joints within {s.joint_margin:.2f} rad of a limit"
    sigma = model.sigma_min(q)
    if sigma < s.min_sigma:
        return f"near a singularity (sigma_min {sigma:.3f} < {s.min_sigma})"
    low = min(model.flange_pose(q)[2, 3], T_cam[2, 3])
    if low < s.min_height_m:
        return f"flange or camera {low:.3f} m above the base plane (< {s.min_height_m})"
    return _board_in_view(model, T_cam, T_base_board, board, s.image_margin_px)


def _board_in_view(model: ArmModel, T_cam: np.ndarray, T_base_board: np.ndarray,
                   board: Board, margin_px: float) -> str:
    intr = model.mount.intrinsics
    w, h = board.size_m
    outline = np.array([[0, 0, 0], [w, 0, 0], [w, h, 0], [0, h, 0]], dtype=float)
    T_cb = invert(T_cam) @ T_base_board
    pts_cam = outline @ T_cb[:3, :3].T + T_cb[:3, 3]
    if np.any(pts_cam[:, 2] <= 0.05):
        return "board behind or too close to the camera"
    if T_cb[:3, 2] @ T_cb[:3, 3] <= 0:  # board z into the board: camera must see its front
        return "camera sees the back of the board"
    uv, _ = cv2.projectPoints(pts_cam, np.zeros(3), np.zeros(3), intr.K, intr.dist)
    uv = uv.reshape(-1, 2)
    inside = ((uv[:, 0] >= margin_px) & (uv[:, 0] <= intr.width - 1 - margin_px)
              & (uv[:, 1] >= margin_px) & (uv[:, 1] <= intr.height - 1 - margin_px))
    if not inside.all():
        return "board would leave the image"
    return ""
