"""The lens's vignetting from the calibration views: the board's white paper as a flat field.

Every view shows the board's white paper at many places in the image. The paper has one
reflectance, and a flat board under a distant light is lit evenly, so within one view the white
paper's brightness changes only by the lens's fall-off ``V``
(:class:`armstereo.photometric.vignetting.Vignetting`); from view to view it changes by an
unknown factor (exposure, white balance, the board's tilt to the light). The fit::

    I[s] = a[view(s)] * (1 + k1 r[s]^2 + k2 r[s]^4)

over samples ``s`` of white paper (grey level ``I``, radius ``r`` from the principal point over
the image's half-diagonal), with one ``a`` per view and ``k1``, ``k2`` shared, by Gauss-Newton
with robust weights (Huber for a few rounds, then Tukey's biweight): a glare on the board's
laminate or a fleck on the lens are outliers, not fall-off. Samples keep a quarter of a square
from any ink (blur and a corner's misfit stay out), away from saturation and from the image
border. The views that put the board into the image corners
(:mod:`armstereo.calibration.coverage`) are what reaches the corners; without them the corners
are extrapolated, and the fit says so (``max_radius``).
"""

from __future__ import annotations

import functools
from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import numpy as np

from armstereo.calibration.board import Board
from armstereo.camera_model import Intrinsics
from armstereo.photometric.vignetting import Vignetting

SAMPLE_STEP_SQUARES = 0.25  # sample grid on the sheet, in squares
INK_CLEARANCE_SQUARES = 0.25  # samples keep this far from any ink
MIN_GREY, MAX_GREY = 20.0, 250.0  # outside: too dark to trust, or saturated
BORDER_PX = 3.0  # samples this close to the image border are left out
HUBER_K = 2.0  # residuals beyond this many robust sigmas are down-weighted (first rounds)
HUBER_ROUNDS = 4
TUKEY_C = 4.685  # then Tukey's biweight: no weight beyond this many robust sigmas
ROUNDS = 14
MIN_SAMPLES = 500
CORNER_RADIUS = 0.85  # the fit reaches the corners when samples lie beyond this radius


@dataclass(frozen=True)
class VignettingFit:
    """The estimated fall-off and how well it is supported: ``samples`` and ``views`` used,
    ``rms_rel`` (robust relative scatter of the white paper about the fit), ``max_radius``
    (largest sampled r: below CORNER_RADIUS the corners are extrapolated), ``k_std`` (standard
    errors of k1, k2)."""

    model: Vignetting
    samples: int
    views: int
    rms_rel: float
    max_radius: float
    k_std: tuple[float, float]

    @property
    def reaches_corners(self) -> bool:
        return self.max_radius >= CORNER_RADIUS

    def as_dict(self) -> dict:
        return {**self.model.as_dict(), "samples": self.samples, "views": self.views,
                "rms_rel": self.rms_rel, "max_radius": self.max_radius,
                "k_std": list(self.k_std), "reaches_corners": self.reaches_corners}


@functools.lru_cache(maxsize=4)
def white_points(board: Board) -> np.ndarray:
    """Board-frame points (N, 3) on white paper at least INK_CLEARANCE_SQUARES from any ink:
    the squares' interiors, the gaps around ChArUco markers and the sheet's margin."""
    img, px_per_m, margin = board.texture
    clearance = int(round(INK_CLEARANCE_SQUARES * board.square_m * px_per_m))
    kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * clearance + 1,) * 2)
    # the sheet ends at its margin: treat outside as ink so samples keep off the edge too
    padded = cv2.copyMakeBorder(img, clearance, clearance, clearance, clearance,
                                cv2.BORDER_CONSTANT, value=0)
    white = cv2.erode((padded > 127).astype(np.uint8), kernel)[clearance:-clearance,
                                                               clearance:-clearance]
    step = SAMPLE_STEP_SQUARES * board.square_m
    xs = np.arange(-margin + step / 2, img.shape[1] / px_per_m - margin, step)
    ys = np.arange(-margin + step / 2, img.shape[0] / px_per_m - margin, step)
    X, Y = np.meshgrid(xs, ys)
    j = np.clip(((X + margin) * px_per_m).astype(int), 0, img.shape[1] - 1)
    i = np.clip(((Y + margin) * px_per_m).astype(int), 0, img.shape[0] - 1)
    keep = white[i, j] > 0
    pts = np.stack([X[keep], Y[keep], np.zeros(int(keep.sum()))], axis=1)
    pts.setflags(write=False)
    return pts


def sample_view(image: np.ndarray, board: Board, intrinsics: Intrinsics,
                T_camera_board: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(u, v, grey) of the board's white paper in one raw view (bilinear, px and grey
    levels), the unusable samples left out."""
    P = white_points(board)
    T = np.asarray(T_camera_board, dtype=float)
    rvec = cv2.Rodrigues(np.ascontiguousarray(T[:3, :3]))[0]
    in_front = (P @ T[:3, :3].T + T[:3, 3])[:, 2] > 0
    if not np.any(in_front):
        empty = np.zeros(0)
        return empty, empty, empty
    uv, _ = cv2.projectPoints(P[in_front], rvec, T[:3, 3], intrinsics.K, intrinsics.dist)
    uv = uv.reshape(-1, 2).astype(np.float32)
    h, w = image.shape[:2]
    inside = ((uv[:, 0] >= BORDER_PX) & (uv[:, 0] <= w - 1 - BORDER_PX)
              & (uv[:, 1] >= BORDER_PX) & (uv[:, 1] <= h - 1 - BORDER_PX))
    uv = uv[inside]
    if len(uv) == 0:
        empty = np.zeros(0)
        return empty, empty, empty
    grey = image.astype(np.float32) if image.ndim == 2 else \
        image.astype(np.float32).mean(axis=2)
    values = cv2.remap(grey, uv[:, 0].reshape(1, -1), uv[:, 1].reshape(1, -1),
                       cv2.INTER_LINEAR).reshape(-1)
    ok = (values > MIN_GREY) & (values < MAX_GREY)
    return uv[ok, 0].astype(float), uv[ok, 1].astype(float), values[ok].astype(float)


def estimate_vignetting(images: Sequence[np.ndarray], board: Board, intrinsics: Intrinsics,
                        T_camera_board: Sequence[np.ndarray]) -> VignettingFit | None:
    """Fit the fall-off (module doc) to the white paper of every view: ``images`` raw
    (uint8), ``T_camera_board`` each view's board pose with the calibrated ``intrinsics``.
    None when fewer than MIN_SAMPLES samples are usable."""
    us, vs, values, view = [], [], [], []
    for k, (img, T) in enumerate(zip(images, T_camera_board, strict=True)):
        u, v, g = sample_view(img, board, intrinsics, T)
        us.append(u)
        vs.append(v)
        values.append(g)
        view.append(np.full(len(g), k))
    I = np.concatenate(values)
    if len(I) < MIN_SAMPLES:
        return None
    view_idx = np.concatenate(view)
    proto = Vignetting(intrinsics.width, intrinsics.height, (intrinsics.cx, intrinsics.cy),
                       (0.0, 0.0, 0.0))
    u, v = np.concatenate(us), np.concatenate(vs)
    r2 = ((u - proto.center[0]) ** 2 + (v - proto.center[1]) ** 2) / proto.radius ** 2
    k, _, w, sigma = _alternate(I, r2, view_idx, len(images))
    model = Vignetting(proto.width, proto.height, proto.center, (float(k[0]), float(k[1]), 0.0))
    k_std = _k_std(r2, w, sigma)
    used = np.unique(view_idx[w > 0])
    return VignettingFit(model, int(len(I)), int(len(used)), float(sigma),
                         float(np.sqrt(r2.max())), k_std)


def _alternate(I: np.ndarray, r2: np.ndarray, view: np.ndarray, n_views: int):
    """(k (2,), a (views,), weights, robust relative sigma): Gauss-Newton on all unknowns at
    once (a view that does not cover the centre trades its scale against the fall-off, which
    alternating between the two only creeps along), robust weights re-estimated each round."""
    basis = np.stack([r2, r2 * r2], axis=1)
    k = np.zeros(2)
    a = np.array([np.median(I[view == i]) if np.any(view == i) else 1.0
                  for i in range(n_views)])
    w = np.ones_like(I)
    sigma = 0.0
    rounds_done = 0
    for _ in range(ROUNDS):
        V = 1.0 + basis @ k
        ai = a[view]
        e = I - ai * V
        # normal equations of e = dI/da da + dI/dk dk, unknowns (a per view, k1, k2)
        Jk = ai[:, None] * basis
        A = np.zeros((n_views + 2, n_views + 2))
        g = np.zeros(n_views + 2)
        A[np.arange(n_views), np.arange(n_views)] = np.bincount(view, w * V * V, n_views)
        for j in range(2):
            A[:n_views, n_views + j] = np.bincount(view, w * V * Jk[:, j], n_views)
        A[n_views:, :n_views] = A[:n_views, n_views:].T
        A[n_views:, n_views:] = (Jk * w[:, None]).T @ Jk
        g[:n_views] = np.bincount(view, w * V * e, n_views)
        g[n_views:] = (Jk * w[:, None]).T @ e
        A[np.arange(n_views), np.arange(n_views)] += 1e-12  # a view with no samples left
        step = np.linalg.solve(A, g)
        a, k = a + step[:n_views], k + step[n_views:]
        rel = I / (a[view] * (1.0 + basis @ k)) - 1.0
        sigma = 1.4826 * float(np.median(np.abs(rel - np.median(rel))))
        w = _weights(rel, sigma, redescending=rounds_done >= HUBER_ROUNDS)
        rounds_done += 1
    return k, a, w, sigma


def _weights(rel: np.ndarray, sigma: float, redescending: bool) -> np.ndarray:
    """Huber weights (a convex start), then Tukey's biweight, which gives a glare's samples
    no weight at all: hundreds of them at a fraction of the weight still pull the fall-off."""
    if not redescending:
        scaled = np.abs(rel) / max(HUBER_K * sigma, 1e-9)
        return np.where(scaled <= 1.0, 1.0, 1.0 / np.maximum(scaled, 1e-12))
    u = rel / max(TUKEY_C * sigma, 1e-9)
    return np.where(np.abs(u) < 1.0, (1.0 - u * u) ** 2, 0.0)


def _k_std(r2: np.ndarray, w: np.ndarray, sigma: float) -> tuple[float, float]:
    """Standard errors of (k1, k2) from the weighted normal equations of the relative
    residuals (per-view scales held: they are many, and barely correlated with the shape)."""
    basis = np.stack([r2, r2 * r2], axis=1) * np.sqrt(w)[:, None]
    try:
        cov = np.linalg.inv(basis.T @ basis) * sigma ** 2
    except np.linalg.LinAlgError:
        return (float("inf"), float("inf"))
    return (float(np.sqrt(cov[0, 0])), float(np.sqrt(cov[1, 1])))
