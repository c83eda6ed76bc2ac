"""Two photographs, no poses: F from the images, Hartley rectification, Birchfield-Tomasi stereo,
and a reconstruction that is metric when focal length and baseline are known.

The path of the terrain-modeling thesis (and of the TASER abstract):

1. match features (SIFT by default: photographs may differ by large viewpoint changes) and
   estimate F robustly (MAGSAC++ by default);
2. rectify with Hartley's method (``cv2.stereoRectifyUncalibrated``), made orientation-safe:
   no mirror image, no upside-down image, and the view taken from further left becomes "left"
   (decided by cheirality, see :func:`_second_camera_side`), so near points get the larger
   disparities as the matcher assumes; the right image is shifted so the matched features'
   disparities start at :data:`DISPARITY_MARGIN_PX`;
3. match the rectified pair with :func:`armstereo.reconstruct.stereo.birchfield`;
4. triangulate every matched pixel through the inverse rectifying homographies:

   * ``metric``: with ``focal_px`` and ``baseline_m``: ``K`` with the principal point at the
     image centre, ``E = K^T F K``, pose by ``cv2.recoverPose`` (cheirality), translation scaled
     to the baseline. Points in metres, in the left camera's frame (x right, y down, z forward);
   * ``similarity``: focal length only: the same with a unit baseline (shape right, scale not);
   * ``projective``: neither: canonical cameras ``[I | 0]``, ``[[e']_x F | e']``. The points are
     the scene up to an unknown 3D projective transformation: straight lines stay straight,
     nothing else (distances, angles, parallelism) is meaningful.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass

import cv2
import numpy as np

from armstereo.epipolar.errors import EpipolarError
from armstereo.epipolar.features import match_features
from armstereo.epipolar.fundamental import estimate_fundamental
from armstereo.epipolar.metrics import sampson_distance
from armstereo.epipolar.projective import apply, cameras_from_fundamental

log = logging.getLogger(__name__)

KINDS = ("metric", "similarity", "projective")
DISPARITY_MARGIN_PX = 8  # matched features' disparities start this far above 0 (and end below
# the search range's top) so the dense matcher sees a little beyond them
CANVAS_MARGIN = 0.25  # canvas extends this share of the input size beyond the features
MAX_CANVAS_SCALE = 2.0  # and is never larger than this multiple of the input's largest side
RECTIFY_THRESHOLD_PX = 5.0  # cv2.stereoRectifyUncalibrated ignores points further off F
MIN_MATCHES = 15


@dataclass(frozen=True)
class UncalibratedRectification:
    """A rectified pair from F alone (images and masks are the rectified left/right views).

    ``H_left``/``H_right`` map ORIGINAL pixels of the left/right view to rectified pixels
    (canvas and disparity shift included); ``swapped`` is True when image 2 became the left
    view. ``F`` relates the inputs in their given order (``x2^T F x1 = 0``); ``x1``/``x2`` are
    the inlier matches (input order, px). Disparities of the features lie in
    ``disparity_range`` (px); ``median_abs_dy_px`` is their median row difference.
    """

    left: np.ndarray
    right: np.ndarray
    left_mask: np.ndarray
    right_mask: np.ndarray
    H_left: np.ndarray
    H_right: np.ndarray
    swapped: bool
    F: np.ndarray
    x1: np.ndarray
    x2: np.ndarray
    disparity_range: tuple[float, float]
    median_abs_dy_px: float

    @property
    def size(self) -> tuple[int, int]:
        return self.left.shape[1], self.left.shape[0]

    def rectified_matches(self) -> tuple[np.ndarray, np.ndarray]:
        """The inlier matches in rectified (left, right) coordinates, ``(N, 2)`` each."""
        xl, xr = (self.x2, self.x1) if self.swapped else (self.x1, self.x2)
        return apply(self.H_left, xl), apply(self.H_right, xr)


def estimate_from_images(image1: np.ndarray, image2: np.ndarray, *, detector: str = "sift",
                         method: str = "magsac") -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(F, x1, x2)``: F of two uint8 images and its inlier matches ((N, 2) px each).

    Raises EpipolarError (or DegenerateError) when the images do not give enough matches.
    """
    m = match_features(image1, image2, detector)
    if len(m) < MIN_MATCHES:
        raise EpipolarError(f"only {len(m)} {detector} matches between the images (need "
                            f"{MIN_MATCHES}): do they show the same scene from nearby views?")
    F, mask = estimate_fundamental(m.x1, m.x2, method)
    return F, m.x1[mask], m.x2[mask]


def rectify_uncalibrated(image1: np.ndarray, image2: np.ndarray, F: np.ndarray, x1: np.ndarray,
                         x2: np.ndarray, *,
                         focal_px: float | None = None) -> UncalibratedRectification:
    """Hartley-rectify two images from F and its inlier matches (see the module doc).

    ``focal_px`` only serves to tell which camera is on the left (cheirality through
    ``cv2.recoverPose``); without it the image width is assumed, which is enough for that.
    """
    size = (image1.shape[1], image1.shape[0])
    ok, H1, H2 = cv2.stereoRectifyUncalibrated(x1, x2, F, size, threshold=RECTIFY_THRESHOLD_PX)
    if not ok:
        raise EpipolarError("Hartley rectification failed for this fundamental matrix")
    H1, H2 = _upright(_positive(H1, size), _positive(H2, size), size)
    swapped = _second_camera_side(F, x1, x2, H1, size, focal_px) < 0
    if swapped:  # camera 2 sits left of camera 1: image 2 is the left view
        H1, H2 = H2, H1
    xl, xr = (x2, x1) if swapped else (x1, x2)
    Hl, Hr = _place(H1, H2, xl, xr, size)
    il, ir = (image2, image1) if swapped else (image1, image2)
    canvas = _canvas_size(Hl, Hr, xl, size)
    left, lmask = _warp(il, Hl, canvas)
    right, rmask = _warp(ir, Hr, canvas)
    pl, pr = apply(Hl, xl), apply(Hr, xr)
    disp = pl[:, 0] - pr[:, 0]
    return UncalibratedRectification(
        left, right, lmask, rmask, Hl, Hr, swapped, F, x1, x2,
        (float(disp.min()), float(disp.max())), float(np.median(np.abs(pl[:, 1] - pr[:, 1]))))


def _centre(size: tuple[int, int]) -> np.ndarray:
    return np.array([[(size[0] - 1) / 2.0, (size[1] - 1) / 2.0]])


def _positive(H: np.ndarray, size: tuple[int, int]) -> np.ndarray:
    """H scaled so the image centre maps with w > 0 (oriented projective geometry: points in
    front keep their side, so directions at infinity keep their sign)."""
    w = (H @ np.r_[_centre(size)[0], 1.0])[2]
    return H if w > 0 else -H


def _jacobian_at_centre(H: np.ndarray, size: tuple[int, int]) -> np.ndarray:
    c = _centre(size)
    return np.column_stack([(apply(H, c + [1.0, 0]) - apply(H, c))[0],
                            (apply(H, c + [0, 1.0]) - apply(H, c))[0]])


def _upright(H1: np.ndarray, H2: np.ndarray, size: tuple[int, int]):
    """Compose both homographies with one flip/turn so image 1 is neither mirrored nor turned
    by more than 90 degrees (rows stay rows: both get the same transformation)."""
    J = _jacobian_at_centre(H1, size)
    fix = np.eye(3)
    if np.linalg.det(J) < 0:
        fix = np.diag([1.0, -1.0, 1.0])  # mirror rows top-bottom: rows map to rows
    if (fix @ np.r_[J[:, 0], 0])[0] < 0:
        fix = np.diag([-1.0, -1.0, 1.0]) @ fix  # half turn
    return fix @ H1, fix @ H2


def _second_camera_side(F, x1, x2, H1, size, focal_px: float | None) -> float:
    """Sign of the rectified x direction in which camera 2's centre lies, seen from camera 1.

    F alone cannot tell (a projective reconstruction may be mirrored in depth); cheirality can:
    ``cv2.recoverPose`` picks the motion that puts the matched points in front of both cameras,
    and the oriented epipole ``K c2`` goes through the (w > 0) rectifying homography.
    """
    w, h = size
    f = float(focal_px) if focal_px else float(w)
    K = np.array([[f, 0.0, (w - 1) / 2.0], [0.0, f, (h - 1) / 2.0], [0.0, 0.0, 1.0]])
    _, R, t, _ = cv2.recoverPose(K.T @ F @ K, x1, x2, K)
    c2 = -R.T @ t.ravel()
    return float((H1 @ K @ c2)[0])


def _place(H1, H2, xl, xr, size):
    """Translate both views onto one canvas (same rows) and shift the right view so the
    features' disparities start at DISPARITY_MARGIN_PX."""
    pl, pr = apply(H1, xl), apply(H2, xr)
    lo = np.min(pl, axis=0) - CANVAS_MARGIN * np.array(size)
    T = np.array([[1.0, 0, -lo[0]], [0, 1.0, -lo[1]], [0, 0, 1.0]])
    shift = float(np.min(pl[:, 0] - pr[:, 0])) - DISPARITY_MARGIN_PX
    S = np.array([[1.0, 0, shift], [0, 1.0, 0], [0, 0, 1.0]])
    return T @ H1, T @ S @ H2


def _canvas_size(Hl: np.ndarray, Hr: np.ndarray, xl: np.ndarray,
                 size: tuple[int, int]) -> tuple[int, int]:
    """Canvas from 0 to the features' far corner plus a margin, capped at MAX_CANVAS_SCALE."""
    hi = np.max(apply(Hl, xl), axis=0) + CANVAS_MARGIN * np.array(size)
    cap = MAX_CANVAS_SCALE * max(size)
    w, h = (int(math.ceil(min(v, cap))) for v in hi)
    return max(w, 1), max(h, 1)


def _warp(image: np.ndarray, H: np.ndarray, canvas: tuple[int, int]):
    out = cv2.warpPerspective(image, H, canvas, flags=cv2.INTER_LINEAR,
                              borderMode=cv2.BORDER_CONSTANT)
    ones = np.full(image.shape[:2], 255, np.uint8)
    mask = cv2.warpPerspective(ones, H, canvas, flags=cv2.INTER_NEAREST)
    mask = cv2.erode(mask, np.ones((3, 3), np.uint8)) > 0  # drop the blended border pixels
    return out, mask


# ------------------------------------------------------------------------------ reconstruction
@dataclass(frozen=True)
class ImageReconstruction:
    """Result of :func:`reconstruct_images`.

    ``points`` (N, 3) float64 and ``colors`` (N, 3) uint8 BGR; ``kind`` in :data:`KINDS`; for
    ``metric``/``similarity`` the points are in the left view's camera frame (metres, or units
    of the baseline) and ``R``/``t`` give the right camera (``X_right = R X_left + t``).
    ``disparity`` is the rectified left view's disparity (px, NaN = none).
    """

    kind: str
    points: np.ndarray
    colors: np.ndarray
    disparity: np.ndarray
    rectification: UncalibratedRectification
    median_sampson_px: float
    K: np.ndarray | None = None
    R: np.ndarray | None = None
    t: np.ndarray | None = None


def reconstruct_images(image1: np.ndarray, image2: np.ndarray, *,
                       focal_px: float | None = None, baseline_m: float | None = None,
                       detector: str = "sift", method: str = "magsac") -> ImageReconstruction:
    """Reconstruct a scene from two uint8 photographs of the same size (see the module doc).

    Raises EpipolarError (exit 6) when the images do not determine the geometry and
    ConfigError for a baseline without a focal length or non-positive values.
    """
    from armstereo.errors import ConfigError

    if image1.shape[:2] != image2.shape[:2]:
        raise EpipolarError(f"the images differ in size: {image1.shape[1]}x{image1.shape[0]} "
                            f"and {image2.shape[1]}x{image2.shape[0]}")
    if baseline_m is not None and focal_px is None:
        raise ConfigError("a baseline needs the focal length too (--focal PX)")
    for name, v in (("focal length", focal_px), ("baseline", baseline_m)):
        if v is not None and not (math.isfinite(v) and v > 0):
            raise ConfigError(f"the {name} must be > 0, got {v}")
    F, x1, x2 = estimate_from_images(image1, image2, detector=detector, method=method)
    rect = rectify_uncalibrated(image1, image2, F, x1, x2, focal_px=focal_px)
    disparity = _dense_disparity(rect)
    pix_l, pix_r, colors = _dense_correspondences(rect, disparity)
    med = float(np.median(sampson_distance(F, x1, x2)))
    if focal_px is None:
        points = _projective_points(rect, pix_l, pix_r)
        return ImageReconstruction("projective", points, colors, disparity, rect, med)
    kind = "metric" if baseline_m is not None else "similarity"
    K, R, t = _pose(rect, focal_px, image1.shape, 1.0 if baseline_m is None else baseline_m)
    points, keep = _metric_points(K, R, t, pix_l, pix_r)
    return ImageReconstruction(kind, points, colors[keep], disparity, rect, med, K, R, t)


def _dense_disparity(rect: UncalibratedRectification) -> np.ndarray:
    from armstereo.reconstruct.stereo import (
        birchfield,  # moves to armstereo.reconstruct.stereo (issue 9)
    )

    top = int(math.ceil(rect.disparity_range[1])) + DISPARITY_MARGIN_PX
    top = min(max(top, 1), rect.size[0] - 1)
    return birchfield(rect.left, rect.right, top, left_mask=rect.left_mask,
                      right_mask=rect.right_mask)


def _dense_correspondences(rect: UncalibratedRectification, disparity: np.ndarray):
    """Original-pixel coordinates of every matched rectified pixel in both views, and colours."""
    v, u = np.nonzero(np.isfinite(disparity) & rect.left_mask)
    d = disparity[v, u].astype(np.float64)
    ul, ur = np.column_stack([u, v]).astype(float), np.column_stack([u - d, v]).astype(float)
    pix_l = apply(np.linalg.inv(rect.H_left), ul)
    pix_r = apply(np.linalg.inv(rect.H_right), ur)
    colors = rect.left[v, u]
    if colors.ndim == 1:
        colors = np.repeat(colors[:, None], 3, axis=1)
    return pix_l, pix_r, np.ascontiguousarray(colors[:, :3], dtype=np.uint8)


def _left_right_F(rect: UncalibratedRectification) -> np.ndarray:
    return rect.F.T if rect.swapped else rect.F


def _projective_points(rect: UncalibratedRectification, pix_l, pix_r) -> np.ndarray:
    P1, P2 = cameras_from_fundamental(_left_right_F(rect))
    X = cv2.triangulatePoints(P1, P2, pix_l.T, pix_r.T).T
    return X[:, :3] / X[:, 3:]


def _pose(rect: UncalibratedRectification, focal_px: float, shape, baseline: float):
    """K (principal point at the image centre), and the right camera's R, t (|t| = baseline)."""
    h, w = shape[:2]
    K = np.array([[focal_px, 0.0, (w - 1) / 2.0], [0.0, focal_px, (h - 1) / 2.0], [0, 0, 1.0]])
    E = K.T @ _left_right_F(rect) @ K
    xl, xr = (rect.x2, rect.x1) if rect.swapped else (rect.x1, rect.x2)
    _, R, t, _ = cv2.recoverPose(E, xl, xr, K)
    return K, R, t.ravel() * baseline


def _metric_points(K, R, t, pix_l, pix_r) -> tuple[np.ndarray, np.ndarray]:
    """Triangulated points in the left camera frame, kept where both cameras see them ahead."""
    P1 = K @ np.hstack([np.eye(3), np.zeros((3, 1))])
    P2 = K @ np.hstack([R, t[:, None]])
    X = cv2.triangulatePoints(P1, P2, pix_l.T, pix_r.T).T
    pts = X[:, :3] / X[:, 3:]
    keep = (pts[:, 2] > 0) & ((pts @ R.T + t)[:, 2] > 0)
    return pts[keep], keep
