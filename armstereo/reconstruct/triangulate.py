"""Disparity -> depth -> 3D points (rectified-left camera, base frame, original left view).

All functions take the disparity of the rectified left image (``x_right = x_left - d``, NaN = no
match) and a :class:`~armstereo.reconstruct.rectified.StereoGeometry`. Depth is
``Z = fx * b / (d - (cx_l - cx_r))`` in metres along the rectified optical axis; pixels whose
``d - (cx_l - cx_r)`` is not positive (a point at or beyond infinity) get NaN. Arithmetic is
float64; outputs are float32 unless a float64 disparity is given (then float64, for exact
checks).
"""

from __future__ import annotations

import cv2
import numpy as np

from armstereo.errors import StereoError
from armstereo.reconstruct.rectified import RectifiedPair, StereoGeometry
from armstereo.transforms import invert, transform_points

VALID_WEIGHT = 1.0 - 1e-3  # share of bilinear weight that must fall on matched pixels
# OpenCV's default of 5 iterations leaves ~1e-2 px at strongly distorted corners
UNDISTORT_CRITERIA = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 30, 1e-10)


def _out_dtype(disparity: np.ndarray) -> type:
    return np.float64 if disparity.dtype == np.float64 else np.float32


def _check(disparity: np.ndarray, geometry: StereoGeometry) -> np.ndarray:
    disparity = np.asarray(disparity)
    if disparity.ndim != 2 or not np.issubdtype(disparity.dtype, np.floating):
        raise StereoError(f"disparity must be a 2D float array, got {disparity.dtype} "
                          f"{disparity.shape}")
    if (disparity.shape[1], disparity.shape[0]) != tuple(geometry.size):
        raise StereoError(f"disparity is {disparity.shape[1]}x{disparity.shape[0]} but the "
                          f"rectified canvas is {geometry.size[0]}x{geometry.size[1]}")
    return disparity


def _depth(disparity: np.ndarray, geometry: StereoGeometry) -> np.ndarray:
    """Float64 rectified depth ``fx b / (d - offset)``; NaN where that is not positive or d is
    NaN."""
    with np.errstate(invalid="ignore", divide="ignore"):
        shifted = disparity.astype(np.float64) - geometry.disparity_offset
        return np.where(shifted > 0, geometry.fx * geometry.baseline / shifted, np.nan)


def depth_from_disparity(disparity: np.ndarray, geometry: StereoGeometry) -> np.ndarray:
    """Depth (m) along the rectified optical axis for every left pixel; NaN where unknown."""
    disparity = _check(disparity, geometry)
    return _depth(disparity, geometry).astype(_out_dtype(disparity))


def points_rect(disparity: np.ndarray, geometry: StereoGeometry) -> np.ndarray:
    """HxWx3 points (m) in the rectified-left camera frame (x right, y down, z forward); NaN rows
    where the depth is unknown."""
    disparity = _check(disparity, geometry)
    z = _depth(disparity, geometry)
    h, w = disparity.shape
    u = np.arange(w, dtype=np.float64)[None, :]
    v = np.arange(h, dtype=np.float64)[:, None]
    pts = np.empty((h, w, 3))
    pts[..., 0] = (u - geometry.cx_left) * z / geometry.fx
    pts[..., 1] = (v - geometry.cy) * z / geometry.fy
    pts[..., 2] = z
    return pts.astype(_out_dtype(disparity))


def point_cloud(disparity: np.ndarray, geometry: StereoGeometry, image: np.ndarray, *,
                mask: np.ndarray | None = None, frame: str = "base"
                ) -> tuple[np.ndarray, np.ndarray]:
    """Valid points as ``(points (N,3) float32 m, colors (N,3) uint8 BGR)``, in row-major
    pixel order.

    ``frame`` is ``"base"`` (through ``geometry.T_base_rectleft``) or ``"rect"`` (rectified left
    camera). Colours come from ``image``, the rectified left image (grey is repeated to BGR).
    ``mask`` (HxW bool) further restricts the pixels used, e.g. to the left validity mask.
    """
    if frame not in ("base", "rect"):
        raise StereoError(f"frame must be 'base' or 'rect', got {frame!r}")
    disparity = _check(disparity, geometry)
    image = np.asarray(image)
    if image.shape[:2] != disparity.shape:
        raise StereoError(f"colour image is {image.shape[1]}x{image.shape[0]} but the disparity "
                          f"is {disparity.shape[1]}x{disparity.shape[0]}")
    with np.errstate(invalid="ignore"):
        valid = disparity > geometry.disparity_offset  # False for NaN
    if mask is not None:
        valid &= np.asarray(mask, dtype=bool)
    idx = np.flatnonzero(valid)  # only the valid pixels, flat indexing (cheapest gather)
    rows, cols = np.divmod(idx, disparity.shape[1])
    z = geometry.fx * geometry.baseline / (disparity.ravel()[idx].astype(np.float64)
                                           - geometry.disparity_offset)
    points = np.empty((len(z), 3))
    points[:, 0] = (cols - geometry.cx_left) * (z / geometry.fx)
    points[:, 1] = (rows - geometry.cy) * (z / geometry.fy)
    points[:, 2] = z
    if frame == "base":
        points = transform_points(geometry.T_base_rectleft, points)
    colors = image.reshape(len(valid.ravel()), -1)[idx]
    if colors.shape[1] == 1:
        colors = np.repeat(colors, 3, axis=1)
    return points.astype(np.float32), np.ascontiguousarray(colors[:, :3], dtype=np.uint8)


def points_in_camera(points_base: np.ndarray, T_base_camera: np.ndarray) -> np.ndarray:
    """Map Nx3 base-frame points into a camera frame given the camera's pose ``T_base_camera``."""
    return transform_points(invert(np.asarray(T_base_camera, dtype=float)), points_base)


def original_to_rectified_pixels(rectified: RectifiedPair) -> tuple[np.ndarray, np.ndarray]:
    """Float32 maps (HxW of the ORIGINAL left image): where each original pixel lands in the
    rectified left image. Lens distortion is undone exactly (OpenCV's iterative undistortion);
    without distortion this is the homography H of the rectification."""
    intr = rectified.left_intrinsics
    u, v = np.meshgrid(np.arange(intr.width, dtype=np.float64),
                       np.arange(intr.height, dtype=np.float64))
    pix = np.stack([u.ravel(), v.ravel()], axis=1)
    if intr.has_distortion:
        out = cv2.undistortPointsIter(pix[:, None, :], intr.K, intr.dist, rectified.R_left_cv,
                                      rectified.geometry.K_left, UNDISTORT_CRITERIA
                                      ).reshape(-1, 2)
    else:
        h = np.c_[pix, np.ones(len(pix))] @ rectified.rectification.H1.T
        out = h[:, :2] / h[:, 2:]
    shape = (intr.height, intr.width)
    return (out[:, 0].reshape(shape).astype(np.float32),
            out[:, 1].reshape(shape).astype(np.float32))


def depth_in_original_view(disparity: np.ndarray, rectified: RectifiedPair) -> np.ndarray:
    """Depth (m, float32, NaN = none) of every pixel of the ORIGINAL (unrectified) left image.

    The rectified and original left cameras share their optical centre, so each original pixel's
    ray is one rectified pixel's ray: sample the disparity there (bilinear, only where every
    neighbour with weight is matched; disparity is affine in the pixel coordinates on planes, so
    this is exact for planar patches), turn it into rectified depth and re-express the same 3D
    point's depth along the original optical axis. No z-buffer is needed (no parallax), there are
    no holes from forward projection, and every value lies exactly on its pixel's ray.
    """
    geometry = rectified.geometry
    disparity = _check(disparity, geometry).astype(np.float32)
    mx, my = original_to_rectified_pixels(rectified)
    known = np.isfinite(disparity)
    filled = np.where(known, disparity, 0.0).astype(np.float32)
    num = cv2.remap(filled, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT,
                    borderValue=0.0)
    den = cv2.remap(known.astype(np.float32), mx, my, cv2.INTER_LINEAR,
                    borderMode=cv2.BORDER_CONSTANT, borderValue=0.0)
    with np.errstate(invalid="ignore", divide="ignore"):
        d = np.where(den >= VALID_WEIGHT, num / den, np.nan)
    z_rect = _depth(d, geometry)
    # Normalised rectified ray (x', y', 1) of each original pixel, rotated back to the original
    # camera: its z component scales rectified depth to original depth.
    xr = (mx.astype(np.float64) - geometry.cx_left) / geometry.fx
    yr = (my.astype(np.float64) - geometry.cy) / geometry.fy
    col = rectified.R_left_cv[:, 2]  # third row of R_cv^T
    scale = col[0] * xr + col[1] * yr + col[2]
    return (z_rect * scale).astype(np.float32)
