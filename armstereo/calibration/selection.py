"""Choose the hand-eye that predicts left-out views best: the refinement or a closed form.

The joint refinement is the maximum-likelihood hand-eye under its model (Gaussian corner noise,
independent per-view arm pose errors). When the arm is good it beats the closed forms by 2-3x
(bench/results/calibrate.md). When the arm's error is large and systematic (a robot without
calibrated kinematics: 2 mm per view on the Franka sessions of bench/results/calibrate_real.md),
the model is wrong in a way the images cannot reveal, and a closed form, which fits the poses'
relative motions directly, can predict a view from its arm pose better.

This matters only when the arm's poses, not the images, limit the result: the refinement's
left-out views must be predicted more than POSE_LIMITED_FACTOR times worse than its own fit,
and more than POSE_LIMITED_MM off. Otherwise (a good arm, or calibrated kinematics) the
refinement is kept: its held-out pixels are then mostly corner noise and cannot tell a
hand-eye 0.3 mm off from one 1 mm off
(simulations), while its truth error is a third of the closed forms'. The millimetre gate
matters once the corners are clean: on the realistic mock cell (an arm good to a tenth of a
millimetre) the held-out views are 0.1 mm off and their pixels three times the fit's, and a
closed form "won" on noise in 3 of 30 cells, once at 0.43 mm true error against the
refinement's 0.16 mm (bench/results/calibration_prediction.md); the real Franka sessions
without calibrated kinematics are predicted 2-3 mm off (bench/results/calibrate_real.md).

Then the refinement and the closed forms (Andreff's left out, see CANDIDATE_METHODS) are scored
the same way the report scores the result: leave each view out,
fit on the others, predict that view's corners from its recorded arm pose (median over views of
the per-view RMS, px). The refinement's numbers come from the report's leave-one-out; each
closed form is refitted without each view (cheap) with the refined intrinsics and its board pose
the mean of ``T_base_flange @ X @ T_camera_board``. The best candidate gives the mount's
hand-eye if it beats the refinement by SELECTION_MARGIN; the refined intrinsics are kept
whatever wins. Its leave-one-out spread is the
predicted error.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from armstereo.calibration.board import Detection
from armstereo.calibration.consensus import prediction_error_mm, prediction_error_px
from armstereo.calibration.handeye import METHODS, motion_pairs
from armstereo.calibration.handeye_pairs import PairData, solve_pairs
from armstereo.calibration.intrinsics import board_pose
from armstereo.calibration.poses import mean_pose, rotvec
from armstereo.camera_model import Intrinsics

REFINED = "refined"
POSE_LIMITED_FACTOR = 2.0  # held-out RMS over fit RMS (px) above which poses limit the fit
POSE_LIMITED_MM = 1.0  # ... when the left-out views are also predicted this far off (RMS, mm)
# Andreff's linear system solves the translation with an unconstrained rotation: 15-30 % worse
# translations in every simulation (bench/results/calibrate.md), and picked by chance it cost
# 1.4 mm on one of them. Each further candidate is one more chance for a lucky draw.
CANDIDATE_METHODS = tuple(m for m in METHODS if m != "andreff")
# A closed form must predict left-out views this much better than the refinement to replace
# it: the held-out medians of a dozen views are noisy, and near-ties are no evidence.
SELECTION_MARGIN = 0.05


@dataclass(frozen=True)
class Candidate:
    """One hand-eye candidate: its X and board pose (all views), each view's held-out
    prediction error (px RMS), and the jackknife standard errors of X (m, deg per axis)."""

    name: str
    T_flange_camera: np.ndarray
    T_base_board: np.ndarray
    held_out_px: np.ndarray
    translation_se_m: np.ndarray
    rotation_se_deg: np.ndarray
    held_out_mm: np.ndarray

    @property
    def score(self) -> float:
        return float(np.median(self.held_out_px)) if len(self.held_out_px) else math.inf


def closed_form_candidates(detections: Sequence[Detection],
                           T_base_flange: Sequence[np.ndarray],
                           intrinsics: Intrinsics) -> list[Candidate]:
    """Each closed-form method with its leave-one-out prediction errors (module docstring)."""
    F = [np.asarray(T, float) for T in T_base_flange]
    T_cb = [board_pose(d, intrinsics) for d in detections]
    pairs = [p for p in motion_pairs(F, T_cb) if p.usable]
    n = len(F)
    if len(pairs) < 2:
        return []
    data = PairData.of(np.array([p.A for p in pairs]), np.array([p.B for p in pairs]))
    ends = np.array([(p.i, p.j) for p in pairs])
    out = []
    for name in CANDIDATE_METHODS:
        full = _solve(name, data, np.ones(len(pairs)))
        if full is None:
            continue
        held, held_mm, xs = [], [], []
        for i in range(n):
            X = _solve(name, data, np.all(ends != i, axis=1).astype(float))
            if X is None:
                held.append(math.inf)
                held_mm.append(math.inf)
                continue
            B = mean_pose([F[k] @ X @ T_cb[k] for k in range(n) if k != i])
            held.append(prediction_error_px(detections[i], F[i], X, B, intrinsics))
            held_mm.append(prediction_error_mm(T_cb[i], F[i], X, B,
                                               detections[i].object_points))
            xs.append(X)
        if len(xs) < 2:
            continue
        t_se, r_se = _jackknife(full, xs)
        B_full = mean_pose([F[k] @ full @ T_cb[k] for k in range(n)])
        out.append(Candidate(name, full, B_full, np.array(held), t_se, r_se,
                             np.array(held_mm)))
    return out


def choose(candidates: Sequence[Candidate]) -> Candidate:
    """The candidate with the smallest median held-out prediction error, if it beats the
    first one (the refinement) by SELECTION_MARGIN; the first one otherwise."""
    best = min(candidates, key=lambda c: c.score)
    if best.score < (1.0 - SELECTION_MARGIN) * candidates[0].score:
        return best
    return candidates[0]


def selection_report(candidates: Sequence[Candidate], chosen: Candidate,
                     pose_limited: bool) -> dict:
    """``quality.selection``: what was compared and what won."""
    return {
        "chosen": chosen.name,
        "pose_limited": pose_limited,
        "held_out_median_px": {c.name: c.score for c in candidates},
        "basis": "each view predicted from its recorded arm pose by the candidate fitted "
                 "without it (median over views of the per-view RMS); the refined intrinsics "
                 "are used whatever wins",
    }


def _solve(method: str, data: PairData, weights: np.ndarray) -> np.ndarray | None:
    try:
        X = solve_pairs(method, None, None, weights, data=data)
    except (np.linalg.LinAlgError, ValueError):
        return None
    return X if np.all(np.isfinite(X)) else None


def _jackknife(X_full: np.ndarray, xs: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    R0 = X_full[:3, :3]
    t = np.array([R0.T @ (X[:3, 3] - X_full[:3, 3]) for X in xs])
    r = np.array([rotvec(R0.T @ X[:3, :3]) for X in xs])
    m = len(xs)

    def se(v):
        dev = v - v.mean(axis=0)
        return np.sqrt((m - 1) / m * np.sum(dev**2, axis=0))

    return se(t), np.degrees(se(r))


@dataclass(frozen=True)
class Chosen:
    """The winning candidate and the report entry of the comparison."""

    name: str
    T_flange_camera: np.ndarray
    T_base_board: np.ndarray
    report: dict


def choose_hand_eye(detections: Sequence[Detection], T_base_flange: Sequence[np.ndarray],
                    refined, loo):
    """(Chosen, LeaveOneOut of the winner): the refinement (``refined``, with its
    leave-one-out ``loo``) against every closed form on the same views."""
    from armstereo.calibration.report import LeaveOneOut

    ref = Candidate(REFINED, refined.T_flange_camera, refined.T_base_board,
                    loo.held_out_rms_px, loo.translation_se_m, loo.rotation_se_deg,
                    loo.held_out_mm)
    candidates = [ref, *closed_form_candidates(detections, T_base_flange, refined.intrinsics)]
    held_out_mm = float(np.sqrt(np.mean(loo.held_out_mm**2))) if len(loo.held_out_mm) else 0.0
    pose_limited = (loo.held_out_rms_all_px > POSE_LIMITED_FACTOR * refined.rms_px
                    and held_out_mm > POSE_LIMITED_MM)
    best = choose(candidates) if pose_limited else ref
    chosen = Chosen(best.name, best.T_flange_camera, best.T_base_board,
                    selection_report(candidates, best, pose_limited))
    if best is ref:
        return chosen, loo
    px = best.held_out_px
    return chosen, LeaveOneOut(best.translation_se_m, best.rotation_se_deg, px,
                               float(np.sqrt(np.mean(px**2))), best.held_out_mm)
