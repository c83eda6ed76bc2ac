"""Views from a stream: the images shot while the camera was at rest, and stereo pairs of them.

A camera driver records at a steady rate while the arm moves and stops; only an image whose
camera did not move (within ``still_m`` and ``still_deg``) for ``window_s`` around its stamp is
sharp and has the pose TF says. Consecutive still images at one place are one rest; each rest
gives one view, its middle image. Two consecutive views form a pair when their camera centres
are ``baseline`` apart (within ``tolerance``) and their motion passes capture's check (not a
pure rotation, no epipole inside an image: :func:`armstereo.epipolar.motion.classify_motion`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from armstereo import validate
from armstereo.camera_model import Intrinsics
from armstereo.epipolar.motion import classify_motion


@dataclass(frozen=True, kw_only=True)
class RestOptions:
    """``window_s``: how long the camera must be still around an image (half before, half
    after, s); ``still_m`` / ``still_deg``: how far it may move meanwhile (m, deg);
    ``samples``: poses looked at across the window."""

    window_s: float = 0.2
    still_m: float = 1e-4
    still_deg: float = 0.02
    samples: int = 9

    def __post_init__(self) -> None:
        validate.positive(self.window_s, "still window", "s", cap=60.0)
        validate.positive(self.still_m, "still tolerance", "m", cap=0.1)
        validate.positive(self.still_deg, "still angle", "deg", cap=10.0)
        validate.whole(self.samples, "samples", 3, 101)


def still_mask(stamps: np.ndarray, poses, options: RestOptions) -> np.ndarray:
    """True for each image stamp (ns) around which the camera stayed still (see module)."""
    stamps = np.asarray(stamps, dtype=np.int64).reshape(-1)
    if not len(stamps):
        return np.zeros(0, bool)
    half = int(round(options.window_s * 1e9 / 2))
    offsets = np.linspace(-half, half, options.samples).round().astype(np.int64)
    times = (stamps[:, None] + offsets[None, :]).reshape(-1)
    T_bf, T_fc, valid = poses.at(times)
    T = (T_bf @ T_fc).reshape(len(stamps), options.samples, 4, 4)
    centre = T[:, options.samples // 2]
    moved = np.linalg.norm(T[:, :, :3, 3] - centre[:, None, :3, 3], axis=2).max(axis=1)
    turned = np.degrees(_angles(centre[:, None, :3, :3], T[:, :, :3, :3])).max(axis=1)
    ok = valid.reshape(len(stamps), options.samples).all(axis=1)
    return ok & (moved <= options.still_m) & (turned <= options.still_deg)


def _angles(Ra: np.ndarray, Rb: np.ndarray) -> np.ndarray:
    """Rotation angle (rad) between rotation matrices, broadcast."""
    trace = np.einsum("...ji,...ji->...", Ra, Rb)
    return np.arccos(np.clip((trace - 1.0) / 2.0, -1.0, 1.0))


def rest_views(stamps: np.ndarray, T_cams: np.ndarray, still: np.ndarray,
               options: RestOptions) -> list[tuple[int, float]]:
    """(image index, settle s) per rest: the middle image of each run of consecutive still
    images at one place (a run splits where the camera is more than twice the tolerance
    away), and how long the camera had been still when it was shot (at least half the
    window before the run's first image)."""
    views: list[tuple[int, float]] = []
    run: list[int] = []

    def close_run() -> None:
        if run:
            middle = (stamps[run[0]] + stamps[run[-1]]) / 2
            k = min(run, key=lambda i: abs(stamps[i] - middle))
            views.append((k, (stamps[k] - stamps[run[0]]) / 1e9 + options.window_s / 2))
            run.clear()

    for k in range(len(stamps)):
        if not still[k]:
            close_run()
            continue
        if run and not _same_place(T_cams[run[0]], T_cams[k], options):
            close_run()
        run.append(k)
    close_run()
    return views


def _same_place(Ta: np.ndarray, Tb: np.ndarray, options: RestOptions) -> bool:
    moved = float(np.linalg.norm(Ta[:3, 3] - Tb[:3, 3]))
    turned = math.degrees(float(_angles(Ta[:3, :3], Tb[:3, :3])))
    return moved <= 2 * options.still_m and turned <= 2 * options.still_deg


@dataclass(frozen=True)
class PairChoice:
    """Two views (positions in the view list) that form a pair, the achieved baseline (m)
    and its direction in the left camera's frame (``x``, ``-y``, ... or ``dx,dy,dz``)."""

    left: int
    right: int
    achieved_m: float
    direction: str


def choose_pairs(T_cams: list[np.ndarray], intrinsics: list[Intrinsics],
                 baseline: float | None, tolerance: float) -> tuple[list[PairChoice],
                                                                     list[str]]:
    """Pairs of consecutive views (each view in one pair at most) and why the other
    neighbours were not paired (one line each)."""
    pairs, notes = [], []
    k = 0
    while k + 1 < len(T_cams):
        a, b = T_cams[k], T_cams[k + 1]
        why = _refusal(a, b, intrinsics[k], intrinsics[k + 1], baseline, tolerance)
        if why:
            notes.append(f"views {k} and {k + 1}: {why}")
            k += 1
            continue
        d = a[:3, :3].T @ (b[:3, 3] - a[:3, 3])
        pairs.append(PairChoice(k, k + 1, float(np.linalg.norm(d)), direction_label(d)))
        k += 2
    return pairs, notes


def _refusal(a: np.ndarray, b: np.ndarray, ia: Intrinsics, ib: Intrinsics,
             baseline: float | None, tolerance: float) -> str | None:
    length = float(np.linalg.norm(b[:3, 3] - a[:3, 3]))
    if baseline is not None and abs(length - baseline) > tolerance:
        return (f"{length * 1000:.1f} mm apart, not {baseline * 1000:.1f} +- "
                f"{tolerance * 1000:.1f} mm")
    if ia.size != ib.size:
        return "their images differ in size"
    report = classify_motion(a, b, intrinsics1=ia, intrinsics2=ib)
    if report.kind == "rotation_only" or report.epipole_in_image:
        return "; ".join(report.warnings)
    return None


def direction_label(d: np.ndarray) -> str:
    """``x``, ``-x``, ... when ``d`` lies within 1 degree of a camera axis, else ``dx,dy,dz``
    (unit, four decimals): what ``capture --direction`` takes."""
    u = np.asarray(d, dtype=float) / np.linalg.norm(d)
    axis = int(np.argmax(np.abs(u)))
    if abs(u[axis]) >= math.cos(math.radians(1.0)):
        return ("-" if u[axis] < 0 else "") + "xyz"[axis]
    return ",".join(f"{v:.4f}" for v in u)
