"""Camera and hand-eye calibration from recorded views: the whole computation, data in, data out.

``calibrate_from_views(images, joint_positions, model, board)`` detects the board, estimates
the intrinsics (OpenCV), the hand-eye transform with OpenCV's five closed-form methods, then
refines hand-eye, board pose, intrinsics and per-view arm pose error jointly on the corners'
reprojection error, and measures how good the result is. It returns the calibrated mount (and
its TOML text, the format ``capture`` and ``reconstruct`` read) and a JSON-ready report.
Nothing here moves the arm, opens a device or prints. All poses are in the controller's
``base`` frame; X = T_flange_camera is camera_optical in tool0.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from armstereo.calibration.board import Board, Detection, detect_board
from armstereo.calibration.checks import (
    MIN_CORNER_SPACING_PX,
    CalibrationInputError,
    usable_views,
)
from armstereo.calibration.glare import without_glare
from armstereo.calibration.handeye import (
    HandEyeEstimate,
    check_diversity,
    closed_form_all,
    motion_diversity,
    motion_pairs,
)
from armstereo.calibration.intrinsics import (
    board_pose,
    check_distortion_model,
)
from armstereo.calibration.mount_file import mount_toml
from armstereo.calibration.poses import as_rigid, exp6, mean_pose, pose_difference
from armstereo.calibration.prediction import jackknife_covariance, predicted_error
from armstereo.calibration.refine import PoseErrorPrior, RefineResult, refine_hand_eye
from armstereo.calibration.report import (
    LeaveOneOut,
    arm_error_warnings,
    board_pose_spread,
    error_effects,
    held_out_prediction,
    leave_one_out,
    plausibility_warnings,
    pose_noise_warnings,
    prediction_mm,
    view_warnings,
)
from armstereo.calibration.screening import add_screening, check_fit, screen_session
from armstereo.calibration.selection import REFINED, choose_hand_eye
from armstereo.calibration.vignetting import estimate_vignetting
from armstereo.camera_model import Intrinsics
from armstereo.errors import ConfigError
from armstereo.mount import CameraMount
from armstereo.robot.arm_model import ArmModel
from armstereo.transforms import invert

log = logging.getLogger(__name__)

# Closed-form method whose result starts the refinement (any converges; this one is stable).
INITIAL_METHOD_ORDER = ("park", "tsai", "horaud", "daniilidis", "andreff")


@dataclass(frozen=True)
class CalibrationOptions:
    """How to calibrate.

    ``distortion_model``: OpenCV terms estimated (see intrinsics.DISTORTION_MODELS); the
    default leaves tangential distortion out because it trades off against the principal
    point, which in turn trades one for one against the hand-eye rotation.
    ``refine_intrinsics``: refine K and distortion together with the hand-eye (the arm's
    metric motion pins the focal length down; intrinsics fitted to the same views alone bias
    the hand-eye by millimetres). ``pose_error``: prior for the arm's pose error (its sigmas
    are re-estimated from the data); None trusts forward kinematics exactly.
    ``working_distance_m``: for the error's effect on a scan (default: the median board
    distance of the views). ``screen_views``: leave out views whose image disagrees with
    their pose or whose corners are misread (screening.py); False keeps every usable view.
    ``select_hand_eye``: with ``leave_one_out``, take the hand-eye (refinement or a closed
    form) that predicts left-out views from their arm poses best (selection.py).
    ``vignetting``: estimate the lens's fall-off from the board's white paper
    (:mod:`armstereo.calibration.vignetting`; needs the images, so only
    :func:`calibrate_from_poses` and :func:`calibrate_from_views` do it) and write it into the
    mount file. ``board_shape``: estimate the print's scale error and bow with the rest
    (:mod:`armstereo.calibration.refine`; a real print is neither exactly its spec's size nor
    flat, and either biases the hand-eye and focal length while every residual looks fine).
    ``screen_glare``: leave out the corners a glare on the board lights up
    (:mod:`armstereo.calibration.glare`; needs the images, like ``vignetting``).
    """

    distortion_model: str = "k1k2"
    refine_intrinsics: bool = True
    pose_error: PoseErrorPrior | None = field(default_factory=PoseErrorPrior)
    board_shape: bool = True
    screen_glare: bool = True
    vignetting: bool = True
    leave_one_out: bool = True
    working_distance_m: float | None = None
    screen_views: bool = True
    select_hand_eye: bool = True
    mount_name: str = "calibrated_camera"


@dataclass
class Calibration:
    """The result: the mount (with its TOML text as ``mount.source``), the report (JSON-ready
    dict), and the intermediate fits for whoever wants to dig."""

    mount: CameraMount
    report: dict
    refined: RefineResult
    closed_form: dict[str, HandEyeEstimate]
    views_used: list[int]
    leave_one_out: LeaveOneOut | None

    @property
    def mount_toml(self) -> str:
        return self.mount.source


def calibrate_from_views(images: Sequence[np.ndarray], joint_positions: Sequence[np.ndarray],
                         model: ArmModel, board: Board, *, intrinsics: Intrinsics | None = None,
                         options: CalibrationOptions = CalibrationOptions()) -> Calibration:
    """Calibrate from one image (uint8 grey/BGR) and one joint vector (rad) per view.

    ``model`` gives the forward kinematics (``T_base_flange``; its mount is not used).
    ``intrinsics`` known in advance are held fixed; None estimates them. Raises
    CalibrationInputError (exit 2) with what to change when the views cannot give a
    trustworthy result, ConfigError for malformed input.
    """
    if len(images) != len(joint_positions):
        raise ConfigError(f"{len(images)} images but {len(joint_positions)} joint vectors")
    flanges = [model.flange_pose(q) for q in joint_positions]
    return calibrate_from_poses(images, flanges, board, intrinsics=intrinsics,
                                options=options)


def calibrate_from_poses(images: Sequence[np.ndarray], T_base_flange: Sequence[np.ndarray],
                         board: Board, *, intrinsics: Intrinsics | None = None,
                         options: CalibrationOptions = CalibrationOptions()) -> Calibration:
    """Calibrate from one image (uint8 grey/BGR) and one flange pose (4x4 ``T_base_flange``,
    base frame, metres) per view: for poses recorded by another tool. See
    :func:`calibrate_from_views`."""
    if len(images) != len(T_base_flange):
        raise ConfigError(f"{len(images)} images but {len(T_base_flange)} poses")
    if not images:
        raise CalibrationInputError("no views to calibrate from; record some (15 is good)")
    sizes = {np.shape(img)[1::-1] for img in images}
    if len(sizes) != 1:
        raise ConfigError(f"all views must have one image size, got {sorted(sizes)}")
    detections = [detect_board(img, board) for img in images]
    glare = {}
    if options.screen_glare:
        screened = [without_glare(img, d, board) for img, d in zip(images, detections,
                                                                   strict=True)]
        detections = [d for d, _ in screened]
        glare = {i: g for i, (_, g) in enumerate(screened) if g is not None and g.left_out}
    cal = calibrate_from_detections(detections, T_base_flange, board, sizes.pop(),
                                    intrinsics=intrinsics, options=options)
    if options.screen_glare:
        _add_glare(cal.report, glare)
    if options.vignetting:
        cal = _with_vignetting(cal, images, T_base_flange, board)
    return cal


def _add_glare(report: dict, glare: dict) -> None:
    """``views.glare``: per view with corners under a glare, how many were left out."""
    report["views"]["glare"] = {str(i): g.as_dict() for i, g in glare.items()}


def _with_vignetting(cal: Calibration, images: Sequence[np.ndarray],
                     flanges: Sequence[np.ndarray], board: Board) -> Calibration:
    """``cal`` with the fall-off fitted to its views (report ``vignetting``, the mount file's
    ``[vignetting]`` section); unchanged, with a warning, when too little paper was seen. The
    board poses are the joint refinement's (with its intrinsics and per-view pose errors)."""
    r = cal.refined
    views = cal.views_used
    T_cb = [invert(r.T_flange_camera) @ invert(np.asarray(flanges[i], float) @ exp6(r.delta[k]))
            @ r.T_base_board for k, i in enumerate(views)]
    fit = estimate_vignetting([images[i] for i in views], board, r.intrinsics, T_cb)
    if fit is None:
        cal.report["warnings"].append("too little of the board's white paper was seen to "
                                      "estimate the vignetting; none is written")
        cal.report["vignetting"] = None
        return cal
    cal.report["vignetting"] = fit.as_dict()
    if not fit.reaches_corners:
        cal.report["warnings"].append(
            f"the board never came near the image corners (largest radius "
            f"{fit.max_radius:.2f} of the half-diagonal): the vignetting there is extrapolated; "
            "record views with the board in the corners (--corner-views)")
    m = cal.mount
    text = m.source.rstrip("\n") + "\n\n" + "\n".join(fit.model.toml_lines())
    cal.mount = CameraMount(m.name, m.T_flange_camera, m.intrinsics, text,
                            vignetting=fit.model)
    return cal


def calibrate_from_detections(detections: Sequence[Detection | None],
                              T_base_flange: Sequence[np.ndarray], board: Board,
                              image_size: tuple[int, int], *,
                              intrinsics: Intrinsics | None = None,
                              options: CalibrationOptions = CalibrationOptions()
                              ) -> Calibration:
    """The computation after detection: ``detections[i]`` (None = board not found) seen from
    flange pose ``T_base_flange[i]`` (base frame). See :func:`calibrate_from_views`."""
    check_distortion_model(options.distortion_model)
    if len(detections) != len(T_base_flange):
        raise ConfigError(f"{len(detections)} detections but {len(T_base_flange)} poses")
    size = (int(image_size[0]), int(image_size[1]))
    if intrinsics is not None and intrinsics.size != size:
        raise ConfigError(f"intrinsics are for {intrinsics.width}x{intrinsics.height} images, "
                          f"the views are {size[0]}x{size[1]}")
    views, warnings = usable_views(detections)
    dets = [detections[i] for i in views]
    flanges = [as_rigid(T_base_flange[i], f"T_base_flange of view {i}") for i in views]
    screened = screen_session(views, dets, flanges, board, size, given=intrinsics,
                              distortion_model=options.distortion_model,
                              screen=options.screen_views)
    views, dets, flanges = screened.views, screened.detections, screened.flanges
    warnings += screened.warnings
    intr_fit, intr0 = screened.intrinsics_fit, screened.intrinsics
    T_cb = [board_pose(d, intr0) for d in dets]

    pairs = motion_pairs(flanges, T_cb)
    diversity = motion_diversity(pairs)
    warnings += check_diversity(diversity)
    closed = closed_form_all(flanges, T_cb, pairs)
    start = next((closed[m] for m in INITIAL_METHOD_ORDER if m in closed), None)
    if start is None:
        raise CalibrationInputError("no closed-form hand-eye method found a solution; record "
                                    "views with more varied camera orientations")
    X0 = start.T_flange_camera
    B0 = mean_pose([F @ X0 @ C for F, C in zip(flanges, T_cb, strict=True)])

    refine_k = options.refine_intrinsics and intrinsics is None
    refined = refine_hand_eye(dets, flanges, X0, B0, intr0, pose_error=options.pose_error,
                              refine_intrinsics=refine_k,
                              distortion_model=options.distortion_model,
                              board_shape=options.board_shape, board_center=board.center[:2])
    modelled = options.pose_error is not None
    check_fit(refined.intrinsics, intr0, refined.rms_px, intrinsics_given=intrinsics is not None,
              arm_error_m=refined.pose_sigma_t if modelled else 0.0,
              arm_error_deg=float(np.degrees(refined.pose_sigma_r)) if modelled else 0.0)
    loo = None
    if options.leave_one_out:
        loo = leave_one_out(dets, flanges, refined, trusts_arm=options.pose_error is None,
                            refine_intrinsics=refine_k, distortion_model=options.distortion_model)
    warnings += view_warnings(refined.per_view_rms_px, views)
    if options.pose_error is not None:
        warnings += arm_error_warnings(refined.pose_sigma_t, float(np.degrees(
            refined.pose_sigma_r)), None, refined.rms_px)
    chosen = None
    if loo is not None and options.select_hand_eye:
        chosen, loo = choose_hand_eye(dets, flanges, refined, loo)
    X_final = refined.T_flange_camera if chosen is None else chosen.T_flange_camera
    B_final = refined.T_base_board if chosen is None else chosen.T_base_board
    warnings += plausibility_warnings(X_final)
    fit_mm = np.array([prediction_mm(d, F, X_final, B_final, refined.intrinsics)
                       for d, F in zip(dets, flanges, strict=True)])
    pred = None if loo is None else _prediction(refined, chosen, loo)
    if loo is not None:
        warnings += pose_noise_warnings(_rms_of(loo.held_out_mm), _rms_of(fit_mm),
                                        pred["translation_m"], loo.held_out_rms_all_px,
                                        refined.rms_px)

    T_cb_final = [board_pose(d, refined.intrinsics) for d in dets]
    distances = [float(np.linalg.norm((C @ np.append(board.center, 1.0))[:3]))
                 for C in T_cb_final]
    work_d = options.working_distance_m or float(np.median(distances))
    report = _report(board, len(detections), views, detections, intr_fit, intrinsics,
                     refined, closed, diversity, loo, flanges, T_cb_final, work_d, warnings,
                     options, X_final, pred)
    add_screening(report, screened)
    if chosen is not None:
        report["quality"]["selection"] = chosen.report
    if loo is not None:
        report["quality"]["held_out_prediction"] = held_out_prediction(loo, fit_mm)
        report["quality"]["predicted_error"]["held_out_prediction_mm"] = _rms_of(loo.held_out_mm)
    comments = _mount_comments(board, views, refined, loo, pred)
    if chosen is not None and chosen.name != REFINED:
        comments.append(f"Hand-eye from the {chosen.name} closed form: it predicts left-out "
                        "views from their arm poses better than the joint refinement.")
    text = mount_toml(options.mount_name, X_final, refined.intrinsics, comments)
    mount = CameraMount(options.mount_name, X_final, refined.intrinsics, text)
    for w in warnings:
        log.debug("calibration warning: %s", w)
    return Calibration(mount, report, refined, closed, views, loo)


def _report(board: Board, n_recorded: int, views: list[int],
            detections: Sequence[Detection | None], intr_fit, given: Intrinsics | None,
            refined: RefineResult, closed: dict[str, HandEyeEstimate], diversity, loo,
            flanges, T_cb, work_d: float, warnings: list[str],
            options: CalibrationOptions, X_final: np.ndarray | None = None,
            pred: dict | None = None) -> dict:
    X = refined.T_flange_camera if X_final is None else X_final
    intr = refined.intrinsics
    spread_t, spread_r = board_pose_spread(flanges, X, T_cb)
    delta = refined.delta
    report = {
        "board": board.spec,
        "views": {
            "recorded": n_recorded,
            "used": views,
            "board_not_found": [i for i, d in enumerate(detections) if d is None],
            "board_too_small": [i for i, d in enumerate(detections)
                                if d is not None and d.spacing_px < MIN_CORNER_SPACING_PX],
        },
        "intrinsics": {
            "source": "given" if given is not None else "estimated",
            "distortion_model": options.distortion_model,
            "width": intr.width, "height": intr.height,
            "K": intr.K.tolist(), "dist": intr.dist.tolist(),
            "calibrate_camera_rms_px": None if intr_fit is None else intr_fit.rms_px,
            "calibrate_camera_std_px": None if intr_fit is None else dict(
                zip(("fx", "fy", "cx", "cy"), intr_fit.std.tolist(), strict=True)),
            "refined_with_hand_eye": options.refine_intrinsics and given is None,
        },
        "motion": diversity.as_dict(),
        "closed_form": {name: _closed_entry(est, refined.T_flange_camera)
                        for name, est in closed.items()},
        "refined": {
            "T_flange_camera": refined.T_flange_camera.tolist(),
            "T_camera_flange": invert(refined.T_flange_camera).tolist(),
            "T_base_board": refined.T_base_board.tolist(),
            "board_shape": _shape_entry(refined, board),
            "rms_px": refined.rms_px,
            "per_view_rms_px": refined.per_view_rms_px.tolist(),
            "pixel_sigma_px": refined.pixel_sigma,
            "arm_pose_error": {
                "modelled": options.pose_error is not None,
                "sigma_translation_m": refined.pose_sigma_t if options.pose_error else 0.0,
                "sigma_rotation_deg": float(np.degrees(refined.pose_sigma_r))
                if options.pose_error else 0.0,
                "rms_correction_translation_m": _rms_norm(delta[:, 3:]),
                "rms_correction_rotation_deg": float(np.degrees(_rms_norm(delta[:, :3]))),
            },
        },
        "quality": {
            "board_pose_spread": {
                "translation_m": spread_t, "rotation_deg": spread_r,
                "note": "consistency of the views (noise and arm error), not the accuracy",
            },
        },
        "T_flange_camera": X.tolist(),
        "camera_distance_from_flange_m": float(np.linalg.norm(X[:3, 3])),
        "warnings": warnings,
    }
    if loo is not None:
        report["quality"]["leave_one_out"] = {
            "translation_m": loo.translation_m, "rotation_deg": loo.rotation_deg,
            "translation_se_m": loo.translation_se_m.tolist(),
            "rotation_se_deg": loo.rotation_se_deg.tolist(),
        }
        report["quality"]["held_out_reprojection_px"] = {
            "rms": loo.held_out_rms_all_px, "per_view": loo.held_out_rms_px.tolist(),
        }
        report["quality"]["predicted_error"] = pred
        report["quality"]["effect"] = error_effects(pred["translation_m"], pred["rotation_deg"],
                                                    work_d, intr)
    return report


def _shape_entry(refined: RefineResult, board: Board) -> dict | None:
    """The board as the fit found it: scale error, curvatures, and ``bow_m``: how far its
    outermost corner lies behind its centre (board z; positive: the centre stands out)."""
    if refined.board_shape is None:
        return None
    s, kx, ky = (float(v) for v in refined.board_shape)
    P = np.asarray(board.object_points, dtype=float)
    dx, dy = P[:, 0] - refined.board_center[0], P[:, 1] - refined.board_center[1]
    return {"scale_error_rel": s, "curvature_per_m": [kx, ky],
            "bow_m": float(np.max(kx * dx * dx + ky * dy * dy))}


def _closed_entry(est: HandEyeEstimate, X_refined: np.ndarray) -> dict:
    dt, dr = pose_difference(est.T_flange_camera, X_refined)
    return {"T_flange_camera": est.T_flange_camera.tolist(),
            "residual_rotation_deg": est.residual_rotation_deg,
            "residual_translation_m": est.residual_translation_m,
            "difference_to_refined": {"translation_m": dt, "rotation_deg": dr}}


def _rms_of(v) -> float:
    return float(np.sqrt(np.mean(np.square(v)))) if len(v) else 0.0


def _rms_norm(v: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.sum(v**2, axis=1)))) if len(v) else 0.0


def _prediction(refined: RefineResult, chosen, loo: LeaveOneOut) -> dict:
    """``quality.predicted_error`` (:mod:`armstereo.calibration.prediction`): from the
    refinement's covariance, or the jackknife's for a closed-form hand-eye."""
    if chosen is None or chosen.name == REFINED:
        return predicted_error(refined.covariance_X, "covariance of the joint refinement "
                               "(corner noise and arm pose error estimated from the data)")
    return predicted_error(jackknife_covariance(loo.translation_se_m, loo.rotation_se_deg),
                           f"leave-one-out (jackknife) spread of the {chosen.name} closed form")


def _mount_comments(board: Board, views: list[int], refined: RefineResult,
                    loo: LeaveOneOut | None, pred: dict | None) -> list[str]:
    lines = [f"Calibrated by armstereo from {len(views)} views of {board.spec}; corner RMS "
             f"{refined.rms_px:.3f} px."]
    if loo is not None:
        lines.append(f"Predicted hand-eye error (expected size): "
                     f"{pred['translation_m'] * 1000:.2f} mm, {pred['rotation_deg']:.3f} deg; "
                     f"held-out reprojection {loo.held_out_rms_all_px:.2f} px.")
    return lines
