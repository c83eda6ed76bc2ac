"""How good is a calibration? Numbers that predict the error, and what it means for a scan.

- Leave-one-out (jackknife) variability of the hand-eye: refit without each view in turn;
  ``sqrt((n-1)/n * sum (X_-i - mean)^2)`` estimates the standard error of X. Its norm over the
  three axes is the expected RMS error of the translation (and of the rotation).
- Held-out reprojection error: for each left-out view, its board corners predicted from the
  arm's reported pose and the calibration fitted without it, against what the image shows.
  This includes the arm's own pose error, as a scan will.
- Board pose spread: T_base_flange @ X @ T_camera_board per view should be one pose. Its spread
  measures noise and arm error, *not* the hand-eye error (it cannot see a biased X or biased
  intrinsics): reported for consistency, never used to pick a method.
- Effect: a rotation error of theta (rad) moves the cloud by about d * theta at working
  distance d (9 mm per degree at 0.5 m) and tilts reconstructed surfaces by theta, i.e. by
  theta * W across a view of width W; a translation error moves the cloud by itself but
  cancels inside a pure-translation stereo pair, so it does not change the shape.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field, replace

import numpy as np

from armstereo.calibration.board import Detection
from armstereo.calibration.intrinsics import reprojection_errors
from armstereo.calibration.poses import pose_spread, rotvec
from armstereo.calibration.refine import PoseErrorPrior, RefineResult, refine_hand_eye
from armstereo.camera_model import Intrinsics
from armstereo.transforms import invert

BAD_VIEW_FACTOR = 3.0  # a view whose RMS exceeds this times the median is flagged
# Estimated arm pose error per view above which the user should hear about it.
ARM_ERROR_WARN_M = 0.0003
ARM_ERROR_WARN_DEG = 0.02
HELD_OUT_WARN_FACTOR = 2.0  # held-out reprojection this many times the fit's: arm disagrees
MAX_PLAUSIBLE_CAMERA_DISTANCE_M = 0.3  # camera origin this far from the flange: suspicious
POSE_NOISE_WARN_MM = 1.0  # held-out prediction error (RMS) above which the poses limit ...
POSE_NOISE_FACTOR = 3.0  # ... when it is also this many times the predicted hand-eye error


@dataclass(frozen=True)
class LeaveOneOut:
    """Jackknife over views: standard errors of X (per axis, metres and degrees about the
    flange-frame axes) and the held-out reprojection errors (px, RMS per view)."""

    translation_se_m: np.ndarray  # (3,)
    rotation_se_deg: np.ndarray  # (3,)
    held_out_rms_px: np.ndarray  # (V,)
    held_out_rms_all_px: float
    # (V,) RMS distance (mm) of each left-out view's board corners (PnP) from where its
    # reported pose and the fit without it put them: what a scan placed from that pose sees
    held_out_mm: np.ndarray = field(default_factory=lambda: np.zeros(0))

    @property
    def translation_m(self) -> float:
        """Expected RMS translation error (m): the norm of the per-axis standard errors."""
        return float(np.linalg.norm(self.translation_se_m))

    @property
    def rotation_deg(self) -> float:
        return float(np.linalg.norm(self.rotation_se_deg))


def leave_one_out(detections: Sequence[Detection], T_base_flange: Sequence[np.ndarray],
                  full: RefineResult, *, trusts_arm: bool, refine_intrinsics: bool,
                  distortion_model: str) -> LeaveOneOut:
    """Refit without each view (warm start from ``full``, its sigmas held), then predict that
    view from its reported flange pose."""
    n = len(detections)
    prior = None if trusts_arm else PoseErrorPrior(full.pose_sigma_t, full.pose_sigma_r,
                                                   estimate=False)
    t_dev, r_dev, held, held_sq, held_mm = [], [], [], [], []
    for i in range(n):
        keep = [k for k in range(n) if k != i]
        fit = refine_hand_eye([detections[k] for k in keep], [T_base_flange[k] for k in keep],
                              full.T_flange_camera, full.T_base_board, full.intrinsics,
                              pose_error=prior, refine_intrinsics=refine_intrinsics,
                              distortion_model=distortion_model, pixel_sigma=full.pixel_sigma,
                              estimate_sigmas=False, board_shape=full.board_shape is not None,
                              shape0=full.board_shape, board_center=full.board_center)
        X = fit.T_flange_camera
        t_dev.append(full.T_flange_camera[:3, :3].T @ (X[:3, 3] - full.T_flange_camera[:3, 3]))
        r_dev.append(rotvec(full.T_flange_camera[:3, :3].T @ X[:3, :3]))
        T_cb = invert(X) @ invert(T_base_flange[i]) @ fit.T_base_board
        held_out = replace(detections[i], object_points=fit.object_points(detections[i]))
        e = reprojection_errors(held_out, fit.intrinsics, T_cb)
        held.append(math.sqrt(float(np.mean(e**2))))
        held_sq.append(e**2)
        held_mm.append(prediction_mm(held_out, T_base_flange[i], X, fit.T_base_board,
                                     fit.intrinsics))
    t_se = _jackknife_se(np.array(t_dev))
    r_se = np.degrees(_jackknife_se(np.array(r_dev)))
    return LeaveOneOut(t_se, r_se, np.array(held),
                       math.sqrt(float(np.mean(np.concatenate(held_sq)))), np.array(held_mm))


def prediction_mm(det: Detection, T_base_flange: np.ndarray, T_flange_camera: np.ndarray,
                  T_base_board: np.ndarray, intrinsics: Intrinsics) -> float:
    """RMS distance (mm) of a view's board corners where its image puts them (PnP) from where
    its reported arm pose, the hand-eye and the board pose put them (camera frame)."""
    from armstereo.calibration.consensus import prediction_error_mm
    from armstereo.calibration.intrinsics import board_pose

    return prediction_error_mm(board_pose(det, intrinsics), T_base_flange, T_flange_camera,
                               T_base_board, det.object_points)


def held_out_prediction(loo: LeaveOneOut, fit_mm: np.ndarray) -> dict:
    """``quality.held_out_prediction``: the left-out views' prediction errors in mm beside
    the same number for the views in the fit (reported poses, no pose correction)."""
    return {
        "rms_mm": _rms(loo.held_out_mm), "median_mm": float(np.median(loo.held_out_mm)),
        "per_view_mm": loo.held_out_mm.tolist(),
        "fit_rms_mm": _rms(fit_mm), "fit_median_mm": float(np.median(fit_mm)),
        "basis": "board corners seen in each view (PnP) against where its reported arm pose, "
                 "the hand-eye and the board pose put them; held out: fitted without that "
                 "view. A scan placed from the arm's poses is off by about this much.",
    }


def _rms(v) -> float:
    v = np.asarray(v, float)
    return float(np.sqrt(np.mean(v**2))) if v.size else 0.0


def _jackknife_se(values: np.ndarray) -> np.ndarray:
    n = len(values)
    dev = values - values.mean(axis=0)
    return np.sqrt((n - 1) / n * np.sum(dev**2, axis=0))


def board_pose_spread(T_base_flange: Sequence[np.ndarray], T_flange_camera: np.ndarray,
                      T_camera_board: Sequence[np.ndarray]) -> tuple[float, float]:
    """RMS spread (m, deg) of the board pose in base implied by each view."""
    poses = [F @ T_flange_camera @ C for F, C in zip(T_base_flange, T_camera_board, strict=True)]
    return pose_spread(poses)


def error_effects(translation_m: float, rotation_deg: float, working_distance_m: float,
                  intrinsics: Intrinsics) -> dict:
    """What a hand-eye error means for a scan at ``working_distance_m`` (module docstring)."""
    d = float(working_distance_m)
    theta = math.radians(rotation_deg)
    width = d * intrinsics.width / intrinsics.fx  # view width at that distance (m)
    per_deg = math.radians(1.0)
    return {
        "working_distance_m": d,
        "view_width_m": width,
        "placement_error_m": translation_m + d * theta,
        "placement_m_per_deg": d * per_deg,
        "surface_tilt_m": width * theta,
        "surface_tilt_m_per_deg": width * per_deg,
        "note": ("placement: the whole cloud shifts in the base frame by up to this much; "
                 "surface tilt: depth error from one side of the view to the other; a "
                 "hand-eye translation error cancels inside a pure-translation stereo pair "
                 "(no shape change), a rotation error does not"),
    }


def view_warnings(per_view_rms_px: np.ndarray, views: Sequence[int]) -> list[str]:
    """Flag views whose corners fit much worse than the others."""
    med = float(np.median(per_view_rms_px))
    bad = [(v, e) for v, e in zip(views, per_view_rms_px, strict=True)
           if e > BAD_VIEW_FACTOR * med and e > 0.5]
    return [f"view {v} fits badly ({e:.2f} px RMS, median {med:.2f}): motion blur, a "
            "misdetected corner or the arm still moving?" for v, e in bad]


def arm_error_warnings(sigma_t_m: float, sigma_r_deg: float, held_out_px: float | None,
                       fit_px: float) -> list[str]:
    """Warn when the arm's reported poses disagree with the images by more than a good UR's."""
    out = []
    if sigma_t_m > ARM_ERROR_WARN_M or sigma_r_deg > ARM_ERROR_WARN_DEG:
        out.append(f"the arm's reported poses disagree with the images by about "
                   f"{sigma_t_m * 1000:.2f} mm and {sigma_r_deg:.3f} deg per view (estimated); "
                   "the hand-eye absorbs part of that kinematic error: use the controller's "
                   "calibrated kinematics, not the nominal model")
    if held_out_px is not None and held_out_px > HELD_OUT_WARN_FACTOR * fit_px:
        out.append(f"views left out of the fit are predicted with {held_out_px:.2f} px RMS "
                   f"against {fit_px:.2f} px in the fit: the arm's poses, not the images, "
                   "limit this calibration")
    return out


def pose_noise_warnings(held_out_rms_mm: float, fit_rms_mm: float,
                        predicted_translation_m: float, held_out_px: float,
                        fit_px: float) -> list[str]:
    """Say it in millimetres when the arm's poses, not the images, limit the result: the
    left-out views are predicted more than POSE_NOISE_WARN_MM off, and either much worse than
    the fit's pixels (HELD_OUT_WARN_FACTOR) or than the hand-eye's predicted error accounts
    for (POSE_NOISE_FACTOR)."""
    if not held_out_rms_mm > POSE_NOISE_WARN_MM:
        return []
    if not (held_out_px > HELD_OUT_WARN_FACTOR * fit_px
            or held_out_rms_mm > POSE_NOISE_FACTOR * predicted_translation_m * 1000):
        return []
    return [f"views left out of the fit are predicted {held_out_rms_mm:.2f} mm off (RMS, "
            f"{held_out_px:.2f} px; the fit's corners {fit_px:.2f} px, its views "
            f"{fit_rms_mm:.2f} mm from their reported poses): the arm's poses are noisier "
            "than the images (nominal kinematics, or poses of a TCP or another end-effector "
            f"frame, not the flange); the predicted hand-eye error is "
            f"{predicted_translation_m * 1000:.2f} mm, and a scan placed from these poses "
            f"will be off by about {max(held_out_rms_mm, predicted_translation_m * 1000):.1f} "
            "mm"]


def plausibility_warnings(T_flange_camera: np.ndarray) -> list[str]:
    dist = float(np.linalg.norm(T_flange_camera[:3, 3]))
    if dist > MAX_PLAUSIBLE_CAMERA_DISTANCE_M:
        return [f"the camera comes out {dist:.2f} m from the flange; a wrist camera is "
                "usually within 0.3 m: check that the poses are tool0 in base (not TCP or "
                "base_link)"]
    return []


def report_lines(report: dict) -> list[str]:
    """The report as a few human-readable lines (what the CLI prints without --json)."""
    intr = report["intrinsics"]
    K, d = intr["K"], intr["dist"]
    X = np.asarray(report["T_flange_camera"])
    ref = report["refined"]
    lines = [
        f"intrinsics ({intr['source']}): fx {K[0][0]:.1f} fy {K[1][1]:.1f} cx {K[0][2]:.1f} "
        f"cy {K[1][2]:.1f} px, k1 {d[0]:+.4f} k2 {d[1]:+.4f}; corner RMS {ref['rms_px']:.2f} px",
        "hand-eye T_flange_camera (camera_optical in tool0): t = ("
        + ", ".join(f"{v * 1000:.2f}" for v in X[:3, 3]) + f") mm, camera "
        f"{report['camera_distance_from_flange_m'] * 1000:.0f} mm from the flange",
    ]
    q = report["quality"]
    if "predicted_error" in q:
        p, h, e = q["predicted_error"], q["held_out_reprojection_px"], q["effect"]
        lines += [
            f"predicted error (expected size): {p['translation_m'] * 1000:.2f} mm, "
            f"{p['rotation_deg']:.3f} deg",
            f"held-out views reprojected with {h['rms']:.2f} px (fit {ref['rms_px']:.2f} px)"
            + (f", predicted {q['held_out_prediction']['rms_mm']:.2f} mm off (fit "
               f"{q['held_out_prediction']['fit_rms_mm']:.2f} mm)"
               if "held_out_prediction" in q else ""),
            f"at {e['working_distance_m']:.2f} m the cloud may be placed "
            f"{e['placement_error_m'] * 1000:.1f} mm off and surfaces tilt "
            f"{e['surface_tilt_m'] * 1000:.1f} mm across the view",
        ]
    s = q["board_pose_spread"]
    lines.append(f"board pose spread {s['translation_m'] * 1000:.2f} mm, "
                 f"{s['rotation_deg']:.3f} deg (consistency, not accuracy)")
    lines.append("closed form vs refined: " + ", ".join(
        f"{m} {c['difference_to_refined']['translation_m'] * 1000:.2f} mm / "
        f"{c['difference_to_refined']['rotation_deg']:.3f} deg"
        for m, c in report["closed_form"].items()))
    lines += [f"warning: {w}" for w in report["warnings"]]
    return lines
