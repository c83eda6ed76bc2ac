"""Leave bad views out before the fit, and refuse a fit that is not a camera.

:func:`screen_session` runs before the closed form: views whose corners fit the camera model
far worse than the others' (misread corners) go first, then the consensus over views
(:mod:`consensus`) removes views whose image disagrees with their pose and re-reads
half-turned chessboards. What is left must still be enough for a calibration; the one-line
error otherwise names the views left out and why. :func:`check_fit` refuses a refined result
that is no plausible camera (a focal length run off, a principal point outside the image, views
that do not fit), saying what to change, instead of returning it with a warning.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from armstereo.calibration.board import Board, Detection
from armstereo.calibration.checks import MIN_VIEWS, CalibrationInputError
from armstereo.calibration.consensus import BadView, corner_outliers, screen_views
from armstereo.calibration.intrinsics import (
    IntrinsicsFit,
    calibrate_intrinsics,
    reprojection_errors,
)
from armstereo.camera_model import Intrinsics

log = logging.getLogger(__name__)

# A refined camera farther than these from the start (calibrateCamera or the given one) is no
# refinement but a fit that ran off.
MAX_FOCAL_CHANGE = 0.25  # relative
MAX_ASPECT_DEVIATION = 0.1  # |fy / fx - 1|
MAX_FIT_RMS_PX_PER_KPX = 5.0  # corner RMS allowed per 1000 px of image width (at least 5 px)
# Estimated per-view error of the arm's poses beyond which they are no arm's error but poses
# that do not belong to their images (nominal UR kinematics stay well under 5 mm / 0.5 deg).
MAX_ARM_ERROR_M = 0.01
MAX_ARM_ERROR_DEG = 1.0


@dataclass
class ScreenedViews:
    """Views that go on (indices into the recorded views, their detections with half-turned
    readings corrected, their flange poses), the intrinsics fitted to them (None when given)
    and the start intrinsics, the views left out (original indices) and the warnings."""

    views: list[int]
    detections: list[Detection]
    flanges: list[np.ndarray]
    intrinsics_fit: IntrinsicsFit | None
    intrinsics: Intrinsics
    left_out: list[BadView]
    reread: list[int]
    warnings: list[str]


def screen_session(views: Sequence[int], detections: Sequence[Detection],
                   flanges: Sequence[np.ndarray], board: Board, size: tuple[int, int], *,
                   given: Intrinsics | None, distortion_model: str,
                   screen: bool = True) -> ScreenedViews:
    """Screen the usable views (``views[k]`` is the recorded index of ``detections[k]``).

    With ``screen`` False only the intrinsics are fitted (the old behaviour, for comparison).
    Raises CalibrationInputError when fewer than MIN_VIEWS views survive.
    """
    views, dets, flanges = list(views), list(detections), list(flanges)
    left_out: list[BadView] = []
    fit = _fit(dets, size, given, distortion_model)
    if screen and fit is not None:
        corner_err = [reprojection_errors(d, fit.intrinsics, T)
                      for d, T in zip(dets, fit.T_camera_board, strict=True)]
        bad = corner_outliers(fit.per_view_rms_px, corner_err)
        if bad and len(dets) - len(bad) >= MIN_VIEWS:
            left_out += [BadView(views[k], "corners_misread", f"its corners fit the camera "
                                 f"model with {fit.per_view_rms_px[k]:.2f} px RMS, worst "
                                 f"{np.max(corner_err[k]):.1f} px (median view "
                                 f"{np.median(fit.per_view_rms_px):.2f} px): misdetected "
                                 "corners, blur or glare", float(fit.per_view_rms_px[k]),
                                 float("nan")) for k in bad]
            views, dets, flanges = _keep(views, dets, flanges, set(range(len(dets))) - set(bad))
            fit = _fit(dets, size, given, distortion_model)
    intr = given if fit is None else fit.intrinsics
    reread: list[int] = []
    if screen and len(dets) >= 3:
        s = screen_views(dets, flanges, intr, board)
        for k, det in s.reread.items():
            dets[k] = det
        reread = [views[k] for k in sorted(s.reread)]
        left_out += [BadView(views[b.view], b.kind, b.evidence, b.error_px, b.error_mm)
                     for b in s.bad]
        if s.bad:
            views, dets, flanges = _keep(views, dets, flanges, set(s.kept))
        if (s.bad or s.reread) and given is None:
            fit = _fit(dets, size, given, distortion_model)
            intr = fit.intrinsics
    left_out.sort(key=lambda b: b.view)
    _require_enough(views, left_out)
    warnings = [f"view {b.view} left out ({b.kind.replace('_', ' ')}): {b.evidence}"
                for b in left_out]
    warnings += [f"view {v}: chessboard corners were read half-turned; re-read the other way "
                 "round (it then agrees with the other views)" for v in reread]
    for w in warnings:
        log.info("%s", w)
    return ScreenedViews(views, dets, flanges, fit, intr, left_out, reread, warnings)


def _fit(dets, size, given, distortion_model) -> IntrinsicsFit | None:
    if given is not None:
        return None
    return calibrate_intrinsics(dets, size, distortion_model=distortion_model)


def _keep(views, dets, flanges, keep: set[int]):
    idx = sorted(keep)
    return [views[k] for k in idx], [dets[k] for k in idx], [flanges[k] for k in idx]


def _require_enough(views: list[int], left_out: list[BadView]) -> None:
    if len(views) >= MIN_VIEWS:
        return
    named = "; ".join(f"view {b.view}: {b.kind.replace('_', ' ')}, {b.error_mm:.0f} mm off"
                      for b in left_out[:6])
    raise CalibrationInputError(
        f"only {len(views)} views agree with each other (need >= {MIN_VIEWS}); left out "
        f"{len(left_out)} ({named}): check that each pose belongs to its image (same order, "
        "arm at rest when the image was taken, T_base_flange in metres) and record more views")


def check_fit(intr: Intrinsics, start: Intrinsics, rms_px: float, *,
              intrinsics_given: bool, arm_error_m: float = 0.0,
              arm_error_deg: float = 0.0) -> None:
    """CalibrationInputError (exit 2) when the refined camera or the fit is implausible
    (``arm_error_*``: the estimated per-view pose error of the arm, sigma per axis)."""
    problems = []
    if arm_error_m > MAX_ARM_ERROR_M or arm_error_deg > MAX_ARM_ERROR_DEG:
        problems.append(f"the poses disagree with the images by {arm_error_m * 1000:.0f} mm "
                        f"and {arm_error_deg:.2f} deg per view")
    f0 = (start.fx + start.fy) / 2
    for name, f in (("fx", intr.fx), ("fy", intr.fy)):
        if not np.isfinite(f) or abs(f / f0 - 1) > MAX_FOCAL_CHANGE:
            problems.append(f"{name} ran to {f:.1f} px from {f0:.1f}")
    if not problems and abs(intr.fy / intr.fx - 1) > MAX_ASPECT_DEVIATION:
        problems.append(f"fy / fx = {intr.fy / intr.fx:.3f}")
    if not (0 <= intr.cx < intr.width and 0 <= intr.cy < intr.height):
        problems.append(f"the principal point ({intr.cx:.0f}, {intr.cy:.0f}) left the image")
    limit = MAX_FIT_RMS_PX_PER_KPX * max(1.0, intr.width / 1000.0)
    if not np.isfinite(rms_px) or rms_px > limit:
        problems.append(f"the views fit with {rms_px:.1f} px RMS (more than {limit:.0f})")
    if not problems:
        return
    hint = ("check that the poses are T_base_flange in metres and belong to their images"
            if intrinsics_given else
            "check that the poses are T_base_flange in metres and belong to their images, "
            "or hold the intrinsics (--intrinsics FILE)")
    raise CalibrationInputError(f"the calibration did not converge to a plausible camera "
                                f"({'; '.join(problems)}): {hint}")


def add_screening(report: dict, screened: ScreenedViews) -> None:
    """The screening's findings in the report: ``views.left_out`` (view, kind, evidence,
    error_px, error_mm per view) and ``views.reread_half_turned``."""
    report["views"]["left_out"] = [b.as_dict() for b in screened.left_out]
    report["views"]["reread_half_turned"] = list(screened.reread)
