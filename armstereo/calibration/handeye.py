"""Closed-form hand-eye calibration (eye in hand): the five classic AX = XB methods.

Inputs per view: ``T_base_flange`` (forward kinematics, controller ``base`` frame) and
``T_camera_board`` (board in camera_optical, from PnP). Output: ``T_flange_camera``
(camera_optical in tool0), which is what OpenCV calls ``cam2gripper``.

A motion pair (i, j) is the flange motion ``A = T_base_flange[j]^-1 T_base_flange[i]`` with the
camera motion ``B = T_camera_board[j] T_camera_board[i]^-1``; ``A X = X B``. A pair with a tiny
rotation says almost nothing about X and one near 180 degrees makes the rotation axis (and the
quaternion sign the methods rely on) ill-defined. OpenCV forms *every* pair of the views it is
given, so with OpenCV such pairs can only be avoided by dropping whole views
(:func:`closed_form_views`, kept for comparison). :func:`closed_form_all` instead leaves out
the pairs themselves (:mod:`handeye_pairs`), so every view given keeps its good pairs, and the
closed forms use the same views as the joint refinement (refine.py).
"""

from __future__ import annotations

import logging
import math
from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import numpy as np

from armstereo.calibration.checks import (
    MIN_AXIS_SPREAD_DEG,
    MIN_MAX_ROTATION_DEG,
    MIN_USABLE_PAIRS,
    WEAK_AXIS_SPREAD_DEG,
    CalibrationInputError,
)
from armstereo.calibration.handeye_pairs import solve_pairs
from armstereo.calibration.poses import rotation_angle_deg, rotvec
from armstereo.transforms import invert, make_T

log = logging.getLogger(__name__)

# OpenCV's methods, in the order the report lists them. Always passed as method=...: given
# positionally the fifth argument is an *output* and OpenCV silently runs Tsai.
METHODS = {
    "tsai": cv2.CALIB_HAND_EYE_TSAI,
    "park": cv2.CALIB_HAND_EYE_PARK,
    "horaud": cv2.CALIB_HAND_EYE_HORAUD,
    "andreff": cv2.CALIB_HAND_EYE_ANDREFF,
    "daniilidis": cv2.CALIB_HAND_EYE_DANIILIDIS,
}
MIN_PAIR_ROTATION_DEG = 5.0  # smaller relative rotations: the axis is mostly noise
MAX_PAIR_ROTATION_DEG = 165.0  # larger: axis and quaternion sign become ambiguous


@dataclass(frozen=True)
class MotionPair:
    """Views i < j: flange motion A, camera motion B, A's rotation angle and unit axis."""

    i: int
    j: int
    A: np.ndarray
    B: np.ndarray
    angle_deg: float
    axis: np.ndarray  # in the flange frame of view j; zero for a pure translation

    @property
    def usable(self) -> bool:
        return MIN_PAIR_ROTATION_DEG <= self.angle_deg <= MAX_PAIR_ROTATION_DEG


@dataclass(frozen=True)
class MotionDiversity:
    """How well the views' rotations pin down the hand-eye transform.

    ``max_rotation_deg``: largest flange rotation between two views. ``axis_spread_deg``: how
    far apart the rotation axes of the usable pairs are (0 = all parallel: the translation
    along that axis and part of the rotation are unobservable; 90 = ideal).
    """

    pairs: int
    usable_pairs: int
    small_pairs: int
    near_half_turn_pairs: int
    max_rotation_deg: float
    axis_spread_deg: float

    def as_dict(self) -> dict:
        return {"pairs": self.pairs, "usable_pairs": self.usable_pairs,
                "skipped_small_rotation": self.small_pairs,
                "skipped_near_180": self.near_half_turn_pairs,
                "max_rotation_deg": self.max_rotation_deg,
                "axis_spread_deg": self.axis_spread_deg}


@dataclass(frozen=True)
class HandEyeEstimate:
    """One closed-form solution and its AX = XB residuals over the usable pairs (RMS)."""

    method: str
    T_flange_camera: np.ndarray
    residual_rotation_deg: float
    residual_translation_m: float


def motion_pairs(T_base_flange: Sequence[np.ndarray],
                 T_camera_board: Sequence[np.ndarray]) -> list[MotionPair]:
    """All pairs i < j of the views, with their flange and camera motions."""
    if len(T_base_flange) != len(T_camera_board):
        raise ValueError("one flange pose per board pose")
    out = []
    for i in range(len(T_base_flange)):
        for j in range(i + 1, len(T_base_flange)):
            A = invert(T_base_flange[j]) @ T_base_flange[i]
            B = T_camera_board[j] @ invert(T_camera_board[i])
            angle = rotation_angle_deg(A[:3, :3])
            w = rotvec(A[:3, :3])
            n = float(np.linalg.norm(w))
            out.append(MotionPair(i, j, A, B, angle, w / n if n > 1e-12 else np.zeros(3)))
    return out


def motion_diversity(pairs: Sequence[MotionPair]) -> MotionDiversity:
    """Summarise the pairs' rotations (see :class:`MotionDiversity`)."""
    usable = [p for p in pairs if p.usable]
    small = sum(p.angle_deg < MIN_PAIR_ROTATION_DEG for p in pairs)
    half = sum(p.angle_deg > MAX_PAIR_ROTATION_DEG for p in pairs)
    max_rot = max((p.angle_deg for p in pairs), default=0.0)
    return MotionDiversity(len(pairs), len(usable), int(small), int(half), float(max_rot),
                           _axis_spread_deg(usable))


def _axis_spread_deg(pairs: Sequence[MotionPair]) -> float:
    """Angle spanned by the rotation axes (as lines), weighted by sin^2(angle/2).

    From the scatter matrix S = sum w a a^T with eigenvalues l1 >= l2: 2 atan(sqrt(l2 / l1)),
    which is exactly the angle between the axes for two equally weighted pairs.
    """
    if len(pairs) < 2:
        return 0.0
    S = np.zeros((3, 3))
    for p in pairs:
        w = math.sin(math.radians(p.angle_deg) / 2) ** 2
        S += w * np.outer(p.axis, p.axis)
    lam = np.sort(np.linalg.eigvalsh(S))[::-1]
    if lam[0] <= 0:
        return 0.0
    return math.degrees(2 * math.atan(math.sqrt(max(lam[1], 0.0) / lam[0])))


def check_diversity(div: MotionDiversity) -> list[str]:
    """Raise CalibrationInputError when the rotations cannot determine the hand-eye; return
    warnings when they determine it weakly."""
    if div.max_rotation_deg < MIN_MAX_ROTATION_DEG:
        raise CalibrationInputError(
            f"the views are too similar: the largest rotation between two views is "
            f"{div.max_rotation_deg:.1f} deg (need >= {MIN_MAX_ROTATION_DEG:g}); tilt the "
            "camera more between views (about 20-30 deg around two axes) and roll it")
    if div.usable_pairs < MIN_USABLE_PAIRS:
        raise CalibrationInputError(
            f"only {div.usable_pairs} view pairs rotate between {MIN_PAIR_ROTATION_DEG:g} and "
            f"{MAX_PAIR_ROTATION_DEG:g} deg (need >= {MIN_USABLE_PAIRS}); record views with "
            "more varied camera orientations")
    if div.axis_spread_deg < MIN_AXIS_SPREAD_DEG:
        raise CalibrationInputError(
            f"all rotations between views are about parallel axes (spread "
            f"{div.axis_spread_deg:.1f} deg, need >= {MIN_AXIS_SPREAD_DEG:g}): the hand-eye "
            "translation along that axis is unobservable; tilt the camera about a second, "
            "non-parallel axis too")
    warnings = []
    if div.axis_spread_deg < WEAK_AXIS_SPREAD_DEG:
        warnings.append(f"low rotation diversity: rotation axes span only "
                        f"{div.axis_spread_deg:.0f} deg (>= {WEAK_AXIS_SPREAD_DEG:g} "
                        "recommended); add tilts about another axis and roll")
    if div.max_rotation_deg < 2 * MIN_MAX_ROTATION_DEG:
        warnings.append(f"low rotation diversity: views differ by at most "
                        f"{div.max_rotation_deg:.0f} deg; larger tilts give a better hand-eye")
    return warnings


def closed_form_views(pairs: Sequence[MotionPair], n_views: int) -> list[int]:
    """The views given to OpenCV: drop, one at a time, the view in most unusable pairs until
    every remaining pair is usable (ties: the later view)."""
    keep = set(range(n_views))
    bad = [(p.i, p.j) for p in pairs if not p.usable]
    while True:
        live = [(i, j) for i, j in bad if i in keep and j in keep]
        if not live:
            return sorted(keep)
        counts = np.zeros(n_views, dtype=int)
        for i, j in live:
            counts[i] += 1
            counts[j] += 1
        worst = int(np.flatnonzero(counts == counts.max())[-1])
        keep.discard(worst)


def solve_hand_eye(T_base_flange: Sequence[np.ndarray], T_camera_board: Sequence[np.ndarray],
                   method: str) -> np.ndarray:
    """T_flange_camera from one OpenCV method over all pairs of the given views (>= 3)."""
    if method not in METHODS:
        raise ValueError(f"unknown hand-eye method {method!r}")
    R_g = [np.ascontiguousarray(T[:3, :3]) for T in T_base_flange]
    t_g = [np.ascontiguousarray(T[:3, 3:4]) for T in T_base_flange]
    R_t = [np.ascontiguousarray(T[:3, :3]) for T in T_camera_board]
    t_t = [np.ascontiguousarray(T[:3, 3:4]) for T in T_camera_board]
    R, t = cv2.calibrateHandEye(R_g, t_g, R_t, t_t, method=METHODS[method])
    U, _, Vt = np.linalg.svd(np.asarray(R, dtype=float))
    return make_T(U @ Vt, np.asarray(t, dtype=float).reshape(3))


def ax_xb_residuals(pairs: Sequence[MotionPair], X: np.ndarray) -> tuple[float, float]:
    """RMS over pairs of the rotation (deg) and translation (m) of (A X)^-1 (X B)."""
    rot, trans = [], []
    for p in pairs:
        E = invert(p.A @ X) @ (X @ p.B)
        rot.append(rotation_angle_deg(E[:3, :3]))
        trans.append(float(np.linalg.norm(E[:3, 3])))
    if not rot:
        return math.nan, math.nan
    return float(np.sqrt(np.mean(np.square(rot)))), float(np.sqrt(np.mean(np.square(trans))))


def closed_form_all(T_base_flange: Sequence[np.ndarray], T_camera_board: Sequence[np.ndarray],
                    pairs: Sequence[MotionPair] | None = None) -> dict[str, HandEyeEstimate]:
    """Every method on every usable pair (rotation 5-165 deg) of all the given views.

    Residuals are over the same pairs. A method that fails or returns a non-finite result is
    left out (logged at debug level). CalibrationInputError when fewer than
    MIN_USABLE_PAIRS pairs are usable.
    """
    pairs = motion_pairs(T_base_flange, T_camera_board) if pairs is None else pairs
    usable = [p for p in pairs if p.usable]
    if len(usable) < MIN_USABLE_PAIRS:
        raise CalibrationInputError(
            f"only {len(usable)} view pairs rotate between {MIN_PAIR_ROTATION_DEG:g} and "
            f"{MAX_PAIR_ROTATION_DEG:g} deg (need >= {MIN_USABLE_PAIRS}); record views with "
            "more varied camera orientations")
    A = np.array([p.A for p in usable])
    B = np.array([p.B for p in usable])
    weights = np.ones(len(usable))
    out = {}
    for name in METHODS:
        try:
            X = solve_pairs(name, A, B, weights)
        except (np.linalg.LinAlgError, ValueError) as err:
            log.debug("hand-eye method %s failed: %s", name, err)
            continue
        if not np.all(np.isfinite(X)):
            log.debug("hand-eye method %s gave a non-finite result", name)
            continue
        rot, trans = ax_xb_residuals(usable, X)
        out[name] = HandEyeEstimate(name, X, rot, trans)
    return out
