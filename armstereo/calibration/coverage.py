"""Calibration views that put the board into the image corners. Moves nothing.

The orbit views (:mod:`armstereo.calibration.views`) keep looking at the board's centre, so the
board always sits in the middle of the image. What happens at the image's edges is then only
extrapolated: the lens distortion there, and the vignetting, whose fall-off is largest in the
corners (:mod:`armstereo.calibration.vignetting` samples it on the board's white squares).
Calibration guides ask for the board in every part of the image for that reason. A coverage
view turns the camera from an orbit-like pose so that the board lands near one image corner,
as far out as the planner's checks allow (the whole board inside the image with its margin,
IK on the start's branch, joint limits, singularities, height). All poses in ``base``.
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from armstereo.calibration.board import Board
from armstereo.calibration.poses import rotmat
from armstereo.calibration.views import (
    CalibrationViewPlan,
    PlannedView,
    ViewPlanSettings,
    check_view,
)
from armstereo.errors import IKError
from armstereo.kinematics import ArmModel
from armstereo.transforms import invert, make_T

CORNERS = ((1, 1), (-1, -1), (1, -1), (-1, 1))  # image-corner directions (x right, y down)
# Farther than the start, so the board is small enough to reach the corners (a board filling
# half the image cannot move far from its middle); nearer ones first.
DISTANCE_FACTORS = (1.2, 1.3, 1.4, 1.1)
TILT_DEG = 12.0  # the camera also looks a little across the board (perspective)
ROLL_DEG = (6.0, -6.0, -4.0, 4.0)  # per corner: small, a rolled board is harder to fit
PUSH_ROUNDS = 4  # rounds of moving the board towards the corner until its outline touches
PUSH_SHARE = 0.9  # of the room left each round (the projection changes as the camera turns)


def coverage_views(model: ArmModel, q_start: np.ndarray, plan: CalibrationViewPlan,
                   board: Board, n: int = 4, settings: ViewPlanSettings | None = None
                   ) -> tuple[list[PlannedView], list[str]]:
    """Up to ``n`` views (of the four image corners, in CORNERS order, then again) with the
    board as far into that corner as the checks allow; returns (views, skipped reasons)."""
    settings = settings or ViewPlanSettings()
    start = plan.views[0]
    T0 = start.T_base_camera
    target = (plan.T_base_board @ np.append(board.center, 1.0))[:3]
    d0 = start.distance_m
    views, skipped = [], []
    for k in range(n):
        corner = CORNERS[k % len(CORNERS)]
        view, why = _corner_view(model, q_start, T0, target, d0, corner, ROLL_DEG[k % 4],
                                 plan.T_base_board, board, settings)
        if view is None:
            skipped.append(f"corner view {corner}: {why}")
        else:
            views.append(view)
    return views, skipped


def _corner_view(model: ArmModel, q_start: np.ndarray, T0: np.ndarray, target: np.ndarray,
                 d0: float, corner: tuple[int, int], roll_deg: float, T_base_board: np.ndarray,
                 board: Board, s: ViewPlanSettings) -> tuple[PlannedView | None, str]:
    """The board pushed towards ``corner`` until its outline touches the image margin, at the
    first distance of DISTANCE_FACTORS whose pose passes the checks."""
    sx, sy = corner
    azimuth = math.degrees(math.atan2(sy, sx)) + 90.0  # tilt about an axis across the corner
    why = "no distance tried"
    for factor in DISTANCE_FACTORS:
        T_cam = _pushed(model, T0, target, d0 * factor, corner, azimuth, roll_deg,
                        T_base_board, board, s.image_margin_px + 1.0)
        try:
            q = model.ik(model.flange_pose_for_camera(T_cam), q_start, margin=s.joint_margin)
        except IKError as err:
            why = f"IK: {err}"
            continue
        why = check_view(model, q, T_cam, T_base_board, board, s)
        if not why:
            return PlannedView(model.flange_pose(q), T_cam, q, TILT_DEG, azimuth, roll_deg,
                               d0 * factor), ""
    return None, why


def _pushed(model: ArmModel, T0: np.ndarray, target: np.ndarray, dist: float,
            corner: tuple[int, int], azimuth_deg: float, roll_deg: float,
            T_base_board: np.ndarray, board: Board, margin_px: float) -> np.ndarray:
    """A camera pose whose image holds the board as far towards ``corner`` as fits."""
    intr = model.mount.intrinsics
    sx, sy = corner
    u, v = intr.cx, intr.cy
    for _ in range(PUSH_ROUNDS):
        T_cam = _looking_through(T0, target, dist, (u - intr.cx) / intr.fx,
                                 (v - intr.cy) / intr.fy, azimuth_deg, roll_deg)
        uv = _outline_px(model, T_cam, T_base_board, board)
        room_u = (intr.width - 1 - margin_px - uv[:, 0].max()) if sx > 0 else \
            (uv[:, 0].min() - margin_px)
        room_v = (intr.height - 1 - margin_px - uv[:, 1].max()) if sy > 0 else \
            (uv[:, 1].min() - margin_px)
        u += sx * PUSH_SHARE * room_u
        v += sy * PUSH_SHARE * room_v
    return _looking_through(T0, target, dist, (u - intr.cx) / intr.fx, (v - intr.cy) / intr.fy,
                            azimuth_deg, roll_deg)


def _outline_px(model: ArmModel, T_cam: np.ndarray, T_base_board: np.ndarray,
                board: Board) -> np.ndarray:
    """The squared area's four outer corners in the image (nominal intrinsics), (4, 2) px."""
    intr = model.mount.intrinsics
    w, h = board.size_m
    outline = np.array([[0, 0, 0], [w, 0, 0], [w, h, 0], [0, h, 0]], dtype=float)
    T_cb = invert(T_cam) @ T_base_board
    pts = outline @ T_cb[:3, :3].T + T_cb[:3, 3]
    uv, _ = cv2.projectPoints(pts, np.zeros(3), np.zeros(3), intr.K, intr.dist)
    return uv.reshape(-1, 2)


def _looking_through(T0: np.ndarray, target: np.ndarray, dist: float, xn: float, yn: float,
                     azimuth_deg: float, roll_deg: float) -> np.ndarray:
    """A camera ``dist`` from ``target`` that sees it through normalised image point
    (xn, yn): the start orientation tilted by TILT_DEG (azimuth as the orbit's), rolled, then
    turned so the ray through (xn, yn) points at the target."""
    a = math.radians(azimuth_deg)
    axis = np.array([math.cos(a), math.sin(a), 0.0])
    R_look = T0[:3, :3] @ rotmat(axis * math.radians(TILT_DEG)) @ rotmat(
        [0.0, 0.0, math.radians(roll_deg)])
    d = np.array([xn, yn, 1.0]) / math.sqrt(xn * xn + yn * yn + 1.0)
    # R_align maps the ray d onto the optical axis; the new camera's d is R_look's z
    axis2 = np.cross(d, [0.0, 0.0, 1.0])
    angle = math.asin(min(1.0, float(np.linalg.norm(axis2))))
    R_align = rotmat(axis2 / max(np.linalg.norm(axis2), 1e-12) * angle)
    R = R_look @ R_align
    return make_T(R, target - dist * (R @ d))
