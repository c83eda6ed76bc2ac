"""Find the views whose image disagrees with their pose: consensus over views (LMedS).

The board lies still, so with the right hand-eye X every view's board pose in the base frame,
``T_base_flange[i] @ X @ T_camera_board[i]``, is the same. A view whose recorded pose belongs
to another moment than its image (a stale frame, a moving arm, a pose read late) or whose
corners were read in another order puts the board somewhere else. Least median of squares
over views finds the consensus without knowing the good views in advance:

1. Hypotheses: X from three views at a time (their three motion pairs, Park's method), every
   triple for small sets, a seeded sample of :data:`MAX_HYPOTHESES` triples for large ones.
2. Score: each view's *prediction error*, the RMS distance (mm, camera frame) between the board
   corners where the view sees them (PnP) and where its arm pose, X and the mean board pose of
   the triple put them. Millimetres, not pixels: a pose 17 mm off along the optical axis moves
   the corners by only a few pixels. The hypothesis with the smallest median error over all
   views wins (robust to almost half the views being bad).
3. Threshold: ``max(MIN_THRESHOLD_MM, THRESHOLD_FACTOR * median)``; the winner is refitted on
   the views under it (all their usable pairs) until the set stops changing. Good views of an
   arm with nominal kinematics spread by up to about 3 mm (simulations), so smaller pose
   errors are left to the refinement's pose-error model (they show in the held-out error).
4. Each view over the threshold is explained: a chessboard read half-turned is re-read and
   kept when the other reading agrees; a view whose corners repeat another view's is a stale
   frame; one that fits a neighbour's pose is a pose from another moment; otherwise a bad
   pose. The evidence (pixels and millimetres off) goes into the report.

Corners misread within a view (a few corners off the grid) show up before that, as a view
that fits the intrinsics much worse than the others (:func:`corner_outliers`).
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import cv2
import numpy as np

from armstereo.calibration.board import CHESSBOARD, Board, Detection
from armstereo.calibration.handeye import motion_pairs
from armstereo.calibration.handeye_pairs import PairData, solve_pairs
from armstereo.calibration.intrinsics import board_pose
from armstereo.calibration.poses import mean_pose
from armstereo.camera_model import Intrinsics
from armstereo.transforms import invert

MAX_HYPOTHESES = 120  # triples tried (all of them when there are fewer)
THRESHOLD_FACTOR = 5.0  # times the median prediction error
MIN_THRESHOLD_MM = 5.0  # never tighter: good views of a sloppy arm spread by a few mm
LO_ROUNDS = 5
CORNER_FACTOR = 4.0  # a view fitting the intrinsics this many times worse than the median...
MIN_CORNER_RMS_PX = 1.0  # ... and worse than this: its corners are misread
CORNER_OUTLIER_FACTOR = 10.0  # or a corner this many times the median corner error away...
MIN_CORNER_OUTLIER_PX = 3.0  # ... and at least this far: a corner read at the wrong spot
STALE_PX = 0.5  # corners of two views this close (RMS px): the same image twice


@dataclass(frozen=True)
class BadView:
    """A view left out: its index (in the caller's list), what went wrong (``bad_pose``,
    ``stale_frame``, ``pose_of_another_view``, ``corners_misread``), the evidence as one line,
    and how far off its board is (prediction error, px RMS and mm RMS)."""

    view: int
    kind: str
    evidence: str
    error_px: float
    error_mm: float

    def as_dict(self) -> dict:
        return {"view": self.view, "kind": self.kind, "evidence": self.evidence,
                "error_px": self.error_px, "error_mm": self.error_mm}


@dataclass
class Screening:
    """The outcome: views kept (indices), views left out, chessboard views re-read half-turned
    (index -> corrected detection), the consensus X and board pose, every view's prediction
    error under it (mm) and the threshold used (mm)."""

    kept: list[int]
    bad: list[BadView]
    reread: dict[int, Detection]
    T_flange_camera: np.ndarray
    T_base_board: np.ndarray
    errors_mm: np.ndarray
    threshold_mm: float
    hypotheses: int
    notes: list[str] = field(default_factory=list)


def corner_outliers(per_view_rms_px: np.ndarray,
                    corner_errors_px: Sequence[np.ndarray] | None = None) -> list[int]:
    """Positions of views whose corners fit the camera model far worse than the others': a
    view RMS over CORNER_FACTOR times the median, or single corners over
    CORNER_OUTLIER_FACTOR times the median corner error (``corner_errors_px``: per view,
    each corner's reprojection error under the intrinsics fit)."""
    rms = np.asarray(per_view_rms_px, float)
    if len(rms) < 3:
        return []
    limit = max(MIN_CORNER_RMS_PX, CORNER_FACTOR * float(np.median(rms)))
    bad = set(np.flatnonzero(rms > limit).tolist())
    if corner_errors_px is not None:
        med = float(np.median(np.concatenate([np.asarray(e) for e in corner_errors_px])))
        worst = max(MIN_CORNER_OUTLIER_PX, CORNER_OUTLIER_FACTOR * med)
        bad |= {k for k, e in enumerate(corner_errors_px) if np.max(e) > worst}
    return sorted(int(k) for k in bad)


def screen_views(detections: Sequence[Detection], T_base_flange: Sequence[np.ndarray],
                 intrinsics: Intrinsics, board: Board, *, seed: int = 0) -> Screening:
    """Consensus over the views (module docstring). All lists are aligned; indices in the
    result refer to them. Raises nothing for bad data (the caller decides whether what is
    left is enough)."""
    dets = list(detections)
    F = [np.asarray(T, float) for T in T_base_flange]
    T_cb = [board_pose(d, intrinsics) for d in dets]
    pts = _probe_points(board)
    pairs = _Pairs(motion_pairs(F, T_cb))
    triples = _triples(len(dets), seed)
    best, best_score = None, math.inf
    for tri in triples:
        X = _solve(pairs, set(tri))
        if X is None:
            continue
        B = mean_pose([F[i] @ X @ T_cb[i] for i in tri])
        score = float(np.median(_errors(T_cb, F, X, B, pts)))
        if score < best_score:
            best, best_score = (X, B), score
    if best is None:  # no triple determines X (e.g. parallel rotation axes everywhere)
        n = len(dets)
        return Screening(list(range(n)), [], {}, np.eye(4), np.eye(4), np.zeros(n), math.inf,
                         len(triples), ["no three views determine the hand-eye: nothing "
                                        "screened"])
    X, B = best
    errors = _errors(T_cb, F, X, B, pts)
    threshold = max(MIN_THRESHOLD_MM, THRESHOLD_FACTOR * float(np.median(errors)))
    X, B, errors = _local_refit(T_cb, F, pairs, X, B, errors, threshold, pts)
    reread, bad = _explain(dets, T_cb, F, X, B, intrinsics, board, errors, threshold, pts)
    ok = [i for i in range(len(dets)) if errors[i] <= threshold or i in reread]
    return Screening(ok, bad, reread, X, B, errors, threshold, len(triples))


def _probe_points(board: Board) -> np.ndarray:
    """Board points the errors are measured at: the four outer corners and the centre."""
    w, h = board.size_m
    return np.array([[0, 0, 0], [w, 0, 0], [w, h, 0], [0, h, 0], [w / 2, h / 2, 0]], float)


def _triples(n: int, seed: int) -> list[tuple[int, int, int]]:
    if math.comb(n, 3) <= MAX_HYPOTHESES:
        return list(itertools.combinations(range(n), 3))
    rng = np.random.default_rng(seed)
    out = set()
    while len(out) < MAX_HYPOTHESES:
        out.add(tuple(sorted(int(v) for v in rng.choice(n, 3, replace=False))))
    return sorted(out)


class _Pairs:
    """The usable motion pairs, their solver data computed once, and their views."""

    def __init__(self, pairs):
        use = [p for p in pairs if p.usable]
        self.ends = np.array([(p.i, p.j) for p in use]).reshape(-1, 2)
        self.data = PairData.of(np.array([p.A for p in use]).reshape(-1, 4, 4),
                                np.array([p.B for p in use]).reshape(-1, 4, 4))


def _solve(pairs: _Pairs, views: set[int]) -> np.ndarray | None:
    """Park's X from the usable pairs among ``views``, or None when they do not determine it."""
    inside = np.isin(pairs.ends, list(views)).all(axis=1).astype(float)
    try:
        X = solve_pairs("park", None, None, inside, data=pairs.data)
    except (np.linalg.LinAlgError, ValueError):
        return None
    return X if np.all(np.isfinite(X)) else None


def prediction_error_px(det: Detection, F: np.ndarray, X: np.ndarray, B: np.ndarray,
                        intr: Intrinsics) -> float:
    """RMS pixel distance of the detected corners from those predicted by arm pose F
    (T_base_flange), hand-eye X and board pose B (T_base_board)."""
    T = invert(F @ X) @ B
    if T[2, 3] <= 0:
        return math.inf
    rvec = cv2.Rodrigues(np.ascontiguousarray(T[:3, :3]))[0]
    uv, _ = cv2.projectPoints(det.object_points, rvec, T[:3, 3], intr.K, intr.dist)
    err = uv.reshape(-1, 2) - det.image_points
    value = float(np.sqrt(np.mean(np.sum(err**2, axis=1))))
    return value if math.isfinite(value) else math.inf


def prediction_error_mm(T_camera_board: np.ndarray, F: np.ndarray, X: np.ndarray,
                        B: np.ndarray, points: np.ndarray) -> float:
    """RMS distance (mm) between board ``points`` (board frame, m) where the view sees them
    (``T_camera_board``, PnP) and where arm pose F, hand-eye X and board pose B put them."""
    predicted = invert(F @ X) @ B
    d = (points @ T_camera_board[:3, :3].T + T_camera_board[:3, 3]) - (
        points @ predicted[:3, :3].T + predicted[:3, 3])
    return 1000.0 * float(np.sqrt(np.mean(np.sum(d**2, axis=1))))


def _errors(T_cb, F, X, B, pts) -> np.ndarray:
    """prediction_error_mm of every view at once: ``T_cb`` and ``F`` stacked (n, 4, 4)."""
    C, Fs = np.asarray(T_cb), np.asarray(F)
    Rf_t = np.transpose(Fs[:, :3, :3], (0, 2, 1))
    inv_F = np.zeros_like(Fs)
    inv_F[:, :3, :3], inv_F[:, :3, 3] = Rf_t, -np.einsum("kij,kj->ki", Rf_t, Fs[:, :3, 3])
    inv_F[:, 3, 3] = 1.0
    P = invert(X) @ inv_F @ B  # (n, 4, 4): the board in each camera as the arm puts it
    seen = np.einsum("kij,pj->kpi", C[:, :3, :3], pts) + C[:, None, :3, 3]
    put = np.einsum("kij,pj->kpi", P[:, :3, :3], pts) + P[:, None, :3, 3]
    return 1000.0 * np.sqrt(np.mean(np.sum((seen - put) ** 2, axis=2), axis=1))


def _local_refit(T_cb, F, pairs, X, B, errors, threshold, pts):
    """Refit X (all usable pairs of the views under the threshold) and the board pose until
    the set of views stops changing; returns (X, B, errors)."""
    inl = set(np.flatnonzero(errors <= threshold).tolist())
    for _ in range(LO_ROUNDS):
        X_new = _solve(pairs, inl)
        if X_new is None:
            break
        X = X_new
        B = mean_pose([F[i] @ X @ T_cb[i] for i in sorted(inl)])
        errors = _errors(T_cb, F, X, B, pts)
        new = set(np.flatnonzero(errors <= threshold).tolist())
        if new == inl or len(new) < 3:
            break
        inl = new
    return X, B, errors


def _explain(dets, T_cb, F, X, B, intr, board, errors, threshold, pts):
    """Half-turned re-reads and the evidence for every view over the threshold."""
    reread, bad = {}, []
    for i in np.flatnonzero(errors > threshold):
        i = int(i)
        turned = _half_turned(dets[i], board)
        if turned is not None and prediction_error_mm(board_pose(turned, intr), F[i], X, B,
                                                      pts) <= threshold:
            reread[i] = turned
            continue
        bad.append(_evidence(i, dets, T_cb, F, X, B, intr, errors, threshold, pts))
    return reread, bad


def _half_turned(det: Detection, board: Board) -> Detection | None:
    """A full chessboard detection read the other way round (corner id k <-> N-1-k)."""
    if board.kind != CHESSBOARD or len(det) != board.corner_count:
        return None
    return Detection(det.ids.copy(), det.image_points[::-1].copy(), det.object_points.copy())


def _evidence(i, dets, T_cb, F, X, B, intr, errors, threshold, pts) -> BadView:
    mm = float(errors[i])
    px = prediction_error_px(dets[i], F[i], X, B, intr)
    off = f"its board lands {mm:.1f} mm ({px:.1f} px RMS) from where the other views put it"
    twin = _same_image(i, dets)
    if twin is not None:
        return BadView(i, "stale_frame", f"{off}; its corners repeat view {twin}'s "
                       "(a stale frame: the camera sent an old image)", px, mm)
    for k in (i - 1, i + 1):
        if 0 <= k < len(dets) and prediction_error_mm(T_cb[i], F[k], X, B, pts) <= threshold:
            return BadView(i, "pose_of_another_view", f"{off}; the image fits the pose of "
                           f"view {k} (a pose from another moment: arm still moving, or "
                           "poses and images shifted by one)", px, mm)
    return BadView(i, "bad_pose", f"{off} (more than {threshold:.1f} mm): its recorded pose "
                   "does not belong to its image (arm moving, pose from another moment)",
                   px, mm)


def _same_image(i: int, dets: Sequence[Detection]) -> int | None:
    a = dets[i]
    for k, b in enumerate(dets):
        if k == i or len(b) != len(a) or not np.array_equal(a.ids, b.ids):
            continue
        if float(np.sqrt(np.mean(np.sum((a.image_points - b.image_points) ** 2, axis=1)))) \
                < STALE_PX:
            return k
    return None
