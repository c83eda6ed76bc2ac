"""Depth frames to fuse, from a stereo reconstruction or from a view's recorded ground truth.

A stereo pair's depth lives in its **rectified left** camera: a distortion-free pinhole
(``geometry.K_left``, pixel centres at integer coordinates like every OpenCV image) at pose
``geometry.T_base_rectleft``, which shares its optical centre with the original left camera.
Fusing that depth directly needs no resampling (resampling depth across edges invents
surfaces), and the rectified left image gives the colours.

Ground truth (mock recordings only) is the z-depth of the original view. Where the camera has
lens distortion it is resampled onto the undistorted pinhole with nearest-neighbour lookup
(never blending two surfaces).
"""

from __future__ import annotations

import cv2
import numpy as np

from armstereo.camera_model import Intrinsics
from armstereo.errors import RecordingError
from armstereo.evaluation.depth import visible_mask
from armstereo.fusion.tsdf import DepthFrame, rotate
from armstereo.recording import Pair, View

UNDISTORT_CRITERIA = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 30, 1e-10)


def frame_from_reconstruction(recon) -> DepthFrame:
    """The depth of a reconstruction (:mod:`armstereo.reconstruct.views`) in its rectified left
    camera."""
    geometry = recon.rectified.geometry
    image = recon.rectified.left
    if image.ndim == 2:
        image = cv2.cvtColor(image, cv2.COLOR_GRAY2BGR)
    return DepthFrame(np.asarray(recon.depth_rect, dtype=np.float32), geometry.K_left,
                      geometry.T_base_rectleft, image, recon.pair_index,
                      f"pair {recon.pair_index} (stereo)")


def frame_from_truth(pair: Pair) -> DepthFrame:
    """The left view's ground-truth depth, kept where the right view sees the same surface
    (what a perfect matcher would return); RecordingError without ground truth."""
    left, right = pair.left, pair.right
    if left.depth is None or right.depth is None:
        raise RecordingError(f"pair {pair.index} has no ground-truth depth (not a mock capture)")
    mask = visible_mask(left.depth, left.intrinsics, left.T_base_camera, right.depth,
                        right.intrinsics, right.T_base_camera)
    depth = np.where(mask, left.depth, np.nan).astype(np.float32)
    depth, image = _pinhole(depth, left.image, left.intrinsics)
    return DepthFrame(depth, left.intrinsics.K, left.T_base_camera, image, pair.index,
                      f"pair {pair.index} (ground truth)")


def _pinhole(depth: np.ndarray, image: np.ndarray, intr: Intrinsics):
    """Depth and image resampled from a distorted camera onto its undistorted pinhole (same K),
    nearest neighbour; unchanged without distortion."""
    if image.ndim == 2:
        image = cv2.cvtColor(image, cv2.COLOR_GRAY2BGR)
    if not intr.has_distortion:
        return depth, image
    mx, my = cv2.initUndistortRectifyMap(intr.K, intr.dist, np.eye(3), intr.K, intr.size,
                                         cv2.CV_32FC1)
    depth = cv2.remap(depth, mx, my, cv2.INTER_NEAREST, borderMode=cv2.BORDER_CONSTANT,
                      borderValue=float("nan"))
    image = cv2.remap(image, mx, my, cv2.INTER_NEAREST, borderMode=cv2.BORDER_CONSTANT)
    return depth, image


def view_surface_points(view: View, stride: int = 1) -> np.ndarray:
    """Base-frame points (N, 3) of a view's ground-truth depth at every ``stride``-th pixel
    along both axes: exact points of the true surface, for completeness. Lens distortion is
    undone exactly."""
    if view.depth is None:
        raise RecordingError(f"view {view.index} has no ground-truth depth")
    depth = view.depth[::stride, ::stride]
    v, u = np.nonzero(np.isfinite(depth) & (depth > 0))
    z = depth[v, u].astype(np.float64)
    v, u = v * stride, u * stride
    intr = view.intrinsics
    pix = np.stack([u, v], axis=1).astype(np.float64)
    if intr.has_distortion:
        xy = cv2.undistortPointsIter(pix[:, None, :], intr.K, intr.dist, None, None,
                                     UNDISTORT_CRITERIA).reshape(-1, 2)
    else:
        xy = np.stack([(pix[:, 0] - intr.cx - intr.K[0, 1] * (pix[:, 1] - intr.cy) / intr.fy)
                       / intr.fx, (pix[:, 1] - intr.cy) / intr.fy], axis=1)
    cam = np.column_stack([xy * z[:, None], z])
    T = view.T_base_camera
    return rotate(T[:3, :3], cam) + T[:3, 3]


def seen_by(view: View, points: np.ndarray, tolerance: float) -> np.ndarray:
    """Boolean (N,): base-frame points that ``view`` sees, i.e. its ground-truth depth at their
    (rounded) pixel agrees with their own depth within ``tolerance`` x depth (not hidden)."""
    T = view.T_base_camera
    cam = rotate(T[:3, :3].T, np.asarray(points, dtype=np.float64) - T[:3, 3])
    z = cam[:, 2]
    intr = view.intrinsics
    front = z > 0
    uv = np.full((len(cam), 2), -1.0)
    if intr.has_distortion and front.any():
        uv[front] = cv2.projectPoints(cam[front], np.zeros(3), np.zeros(3), intr.K,
                                      intr.dist)[0].reshape(-1, 2)
    elif front.any():
        x, y = cam[front, 0] / z[front], cam[front, 1] / z[front]
        uv[front, 0] = intr.fx * x + intr.K[0, 1] * y + intr.cx
        uv[front, 1] = intr.fy * y + intr.cy
    iu, iv = np.rint(uv[:, 0]).astype(np.int64), np.rint(uv[:, 1]).astype(np.int64)
    ok = front & (iu >= 0) & (iu < intr.width) & (iv >= 0) & (iv < intr.height)
    out = np.zeros(len(cam), dtype=bool)
    idx = np.flatnonzero(ok)
    d = view.depth[iv[idx], iu[idx]]
    with np.errstate(invalid="ignore"):
        out[idx] = np.abs(d - z[idx]) <= tolerance * z[idx]
    return out
