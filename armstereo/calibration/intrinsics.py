"""Camera intrinsics from board views (OpenCV ``calibrateCamera``) and board poses (PnP).

All reprojection errors are in pixels; ``T_camera_board`` places the board frame in
camera_optical (metres).
"""

from __future__ import annotations

import contextlib
from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import numpy as np

from armstereo.calibration.board import Detection
from armstereo.calibration.poses import rotmat
from armstereo.camera_model import Intrinsics
from armstereo.errors import ConfigError
from armstereo.transforms import make_T

# Which OpenCV distortion terms are estimated; the others are held at zero. k3 needs views far
# into the image corners to be observable and otherwise soaks up noise; the tangential terms
# p1, p2 trade off against the principal point, which trades one for one against the hand-eye
# rotation (1 px at f = 600 px is 0.1 deg), so they are left out unless asked for.
DISTORTION_MODELS = {
    "none": 0,
    "k1k2": 2,
    "k1k2p1p2": 4,
    "k1k2p1p2k3": 5,
}
DEFAULT_DISTORTION = "k1k2"
_FIX_FLAGS = {
    "none": cv2.CALIB_FIX_K1 | cv2.CALIB_FIX_K2 | cv2.CALIB_FIX_K3 | cv2.CALIB_ZERO_TANGENT_DIST,
    "k1k2": cv2.CALIB_FIX_K3 | cv2.CALIB_ZERO_TANGENT_DIST,
    "k1k2p1p2": cv2.CALIB_FIX_K3,
    "k1k2p1p2k3": 0,
}
_CRITERIA = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-12)


@dataclass(frozen=True)
class IntrinsicsFit:
    """Result of :func:`calibrate_intrinsics`.

    ``rms_px`` is OpenCV's overall RMS reprojection error, ``per_view_rms_px`` (V,) per view,
    ``std`` the standard deviations of (fx, fy, cx, cy) in px that OpenCV estimates from the
    residuals, ``T_camera_board`` one pose per view.
    """

    intrinsics: Intrinsics
    rms_px: float
    per_view_rms_px: np.ndarray
    std: np.ndarray
    T_camera_board: list[np.ndarray]
    distortion_model: str


def check_distortion_model(name: str) -> str:
    if name not in DISTORTION_MODELS:
        raise ConfigError(f"distortion model must be one of {', '.join(DISTORTION_MODELS)}, "
                          f"not {name!r}")
    return name


def calibrate_intrinsics(detections: Sequence[Detection], image_size: tuple[int, int], *,
                         distortion_model: str = DEFAULT_DISTORTION) -> IntrinsicsFit:
    """Estimate K and distortion from board views (``image_size`` = (width, height) px).

    Needs at least three views; the planar-target initialisation of OpenCV is used, skew is
    zero and the distortion terms outside ``distortion_model`` are held at zero.
    """
    check_distortion_model(distortion_model)
    if len(detections) < 3:
        raise ConfigError(f"intrinsics need at least 3 board views, got {len(detections)}")
    obj = [d.object_points.astype(np.float32) for d in detections]
    img = [d.image_points.astype(np.float32).reshape(-1, 1, 2) for d in detections]
    w, h = (int(v) for v in image_size)
    flags = _FIX_FLAGS[distortion_model]
    with _one_opencv_thread():
        rms, K, dist, rvecs, tvecs, std_intr, _, per_view = cv2.calibrateCameraExtended(
            obj, img, (w, h), None, None, flags=flags, criteria=_CRITERIA)
    dist = np.asarray(dist, dtype=float).reshape(-1)[:5]
    if dist.size < 5:
        dist = np.pad(dist, (0, 5 - dist.size))
    intr = Intrinsics(w, h, K, dist)
    poses = [make_T(rotmat(r), np.asarray(t, dtype=float).reshape(3))
             for r, t in zip(rvecs, tvecs, strict=True)]
    # calibrateCameraExtended reports per-view RMS over both coordinates together
    per_view = np.asarray(per_view, dtype=float).reshape(-1)
    return IntrinsicsFit(intr, float(rms), per_view,
                         np.asarray(std_intr, dtype=float).reshape(-1)[:4], poses,
                         distortion_model)


@contextlib.contextmanager
def _one_opencv_thread():
    """calibrateCamera sums in parallel, and its last digits then depend on the threads'
    timing; one thread makes a recomputation (``--from``) bit-identical. It is fast anyway."""
    previous = cv2.getNumThreads()
    cv2.setNumThreads(1)
    try:
        yield
    finally:
        cv2.setNumThreads(previous)


def board_pose(detection: Detection, intrinsics: Intrinsics) -> np.ndarray:
    """T_camera_board of one view for known intrinsics (IPPE start, then Levenberg-Marquardt)."""
    obj = detection.object_points.astype(np.float64)
    img = detection.image_points.astype(np.float64).reshape(-1, 1, 2)
    ok, rvec, tvec = cv2.solvePnP(obj, img, intrinsics.K, intrinsics.dist,
                                  flags=cv2.SOLVEPNP_IPPE)
    if not ok:
        ok, rvec, tvec = cv2.solvePnP(obj, img, intrinsics.K, intrinsics.dist,
                                      flags=cv2.SOLVEPNP_ITERATIVE)
    if not ok:
        raise ConfigError("PnP failed on a board view (degenerate corner layout)")
    rvec, tvec = cv2.solvePnPRefineLM(obj, img, intrinsics.K, intrinsics.dist, rvec, tvec)
    return make_T(rotmat(rvec), tvec.reshape(3))


def reprojection_rms(detection: Detection, intrinsics: Intrinsics,
                     T_camera_board: np.ndarray) -> float:
    """RMS (px, over corners, Euclidean) of the corners projected from ``T_camera_board``."""
    err = reprojection_errors(detection, intrinsics, T_camera_board)
    return float(np.sqrt(np.mean(err**2)))


def reprojection_errors(detection: Detection, intrinsics: Intrinsics,
                        T_camera_board: np.ndarray) -> np.ndarray:
    """Per-corner Euclidean reprojection error (px), shape (N,)."""
    rvec = cv2.Rodrigues(np.ascontiguousarray(T_camera_board[:3, :3]))[0]
    proj, _ = cv2.projectPoints(detection.object_points, rvec, T_camera_board[:3, 3],
                                intrinsics.K, intrinsics.dist)
    return np.linalg.norm(proj.reshape(-1, 2) - detection.image_points, axis=1)
