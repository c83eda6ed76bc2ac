"""Do the images agree with the recorded poses? One verdict per stereo pair.

For a pair with intrinsics and recorded ``base``-frame camera poses, features are matched in the
images, outliers are removed by a robust image-only fundamental matrix, and the median Sampson
distance of the remaining matches is measured under the F the poses imply. Matches sit on the
pose-implied epipolar lines to a small fraction of a pixel when poses and intrinsics are right
(0.01-0.05 px on the mock with exact poses, a few tenths on real images); a wrong hand-eye
transform, a slipped bracket or kinematic error moves them off.

Verdicts:

* ``miscalibrated`` when either

  1. the median Sampson distance exceeds ``threshold_px`` (default
     :data:`MISCALIBRATION_THRESHOLD_PX` = 1 px, about where rectified rows stop matching: the
     Birchfield-Tomasi matcher searches along one row, and a Sampson distance of 1 px is a
     vertical offset of about 1.4 px between the views), or
  2. the fitted camera correction (:class:`~armstereo.epipolar.correction.CameraCorrection`)
     has a component the pair determines that exceeds :data:`MAX_ROTATION_DEG` or
     :data:`MAX_TRANSLATION_MM` by more than :data:`CORRECTION_SIGMAS` standard deviations.
     Some errors move matches only by tenths of a pixel yet bend the cloud: a 1 degree yaw
     with a sideways baseline gives 0.2 px but depth errors near 1 % at the image edges.

* ``ok`` otherwise;
* ``inconclusive`` when the images cannot decide (no baseline, fewer than
  :data:`MIN_INLIERS` consistent matches).

Lens distortion is removed from the images first. Views that differ by more than
:data:`PREWARP_MIN_ROTATION_DEG` are matched after warping view 2 onto view 1 with the
homography the recorded poses predict (see :func:`_prewarp`; the poses are only wrong by the
small error being looked for), so the rotation-sensitive Harris/NCC matcher also works on pairs
taken with a turned wrist or from converging viewpoints.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass

import cv2
import numpy as np

from armstereo.camera_model import Intrinsics
from armstereo.epipolar.correction import CameraCorrection, fit_camera_correction
from armstereo.epipolar.errors import DegenerateError
from armstereo.epipolar.features import match_features
from armstereo.epipolar.fundamental import (
    DEFAULT_THRESHOLD_PX,
    HOMOGRAPHY_THRESHOLD_FACTOR,
    estimate_fundamental,
    fundamental_from_poses,
)
from armstereo.epipolar.metrics import sampson_distance
from armstereo.epipolar.motion import MotionReport, classify_motion
from armstereo.epipolar.projective import apply, check_pose

log = logging.getLogger(__name__)

MISCALIBRATION_THRESHOLD_PX = 1.0
MAX_ROTATION_DEG = 0.5
MAX_TRANSLATION_MM = 3.0
CORRECTION_SIGMAS = 3.0
MIN_INLIERS = 30
PREWARP_MIN_ROTATION_DEG = 2.0
VERDICTS = ("ok", "miscalibrated", "inconclusive")
DEFAULT_DETECTOR = "harris"
DEFAULT_METHOD = "magsac"


@dataclass(frozen=True)
class PairCheck:
    """Result of :func:`check_views`. Distances in px, over the inlier matches.

    ``median_sampson_px``: under the pose-implied F (the verdict's measure);
    ``median_sampson_image_px``: under the image-estimated F (what the images alone achieve;
    None when the matches do not determine F, e.g. a flat scene, and a homography removed the
    outliers instead).
    """

    pair: int | None
    verdict: str
    reason: str
    median_sampson_px: float | None
    median_sampson_image_px: float | None
    matches: int
    inliers: int
    threshold_px: float
    motion: MotionReport
    correction: CameraCorrection | None

    def as_dict(self) -> dict:
        """JSON-ready; keys ``pair``, ``median_sampson_px``, ``verdict`` are stable."""
        return {"pair": self.pair, "median_sampson_px": _r(self.median_sampson_px),
                "verdict": self.verdict, "reason": self.reason,
                "median_sampson_image_px": _r(self.median_sampson_image_px),
                "matches": self.matches, "inliers": self.inliers,
                "threshold_px": self.threshold_px, "motion": self.motion.as_dict(),
                "correction": None if self.correction is None else self.correction.as_dict()}


def _r(v: float | None) -> float | None:
    return None if v is None else round(float(v), 4)


def check_pair(pair, **options) -> PairCheck:
    """:func:`check_views` on a recorded :class:`armstereo.recording.Pair` (``left``/``right``
    views with ``image``, ``intrinsics`` and ``T_base_camera``)."""
    a, b = pair.left, pair.right
    return check_views(a.image, b.image, a.intrinsics, a.T_base_camera, b.intrinsics,
                       b.T_base_camera, pair=pair.index, **options)


def check_views(image1: np.ndarray, image2: np.ndarray, intrinsics1: Intrinsics,
                T_base_cam1: np.ndarray, intrinsics2: Intrinsics, T_base_cam2: np.ndarray, *,
                pair: int | None = None, detector: str = DEFAULT_DETECTOR,
                method: str = DEFAULT_METHOD,
                threshold_px: float = MISCALIBRATION_THRESHOLD_PX,
                fit_correction: bool = True) -> PairCheck:
    """Check two views (uint8 images, intrinsics, 4x4 ``T_base_cam`` poses in metres).

    ``detector``/``method`` choose the matcher and the image-only estimator used to reject
    outliers. Raises EpipolarError for malformed input; a pair the images cannot judge gets the
    verdict ``inconclusive`` instead of an error, so a recording's other pairs still get checked.
    """
    T1, T2 = check_pose(T_base_cam1, "T_base_cam1"), check_pose(T_base_cam2, "T_base_cam2")
    motion = classify_motion(T1, T2, intrinsics1=intrinsics1, intrinsics2=intrinsics2)
    base = dict(pair=pair, threshold_px=float(threshold_px), motion=motion)
    if motion.kind == "rotation_only":
        return PairCheck(verdict="inconclusive", reason=motion.warnings[0],
                         median_sampson_px=None, median_sampson_image_px=None, matches=0,
                         inliers=0, correction=None, **base)
    x1, x2 = _matches(image1, image2, intrinsics1, intrinsics2, T1, T2, detector)
    inliers, F_img, note = _inliers(x1, x2, method)
    if inliers.sum() < MIN_INLIERS:
        return PairCheck(verdict="inconclusive", reason=f"only {int(inliers.sum())} consistent "
                         f"matches (need {MIN_INLIERS}){note}", median_sampson_px=None,
                         median_sampson_image_px=None, matches=len(x1),
                         inliers=int(inliers.sum()), correction=None, **base)
    x1, x2 = x1[inliers], x2[inliers]
    F_pose = fundamental_from_poses(intrinsics1.K, intrinsics2.K, T1, T2)
    med = float(np.median(sampson_distance(F_pose, x1, x2)))
    med_img = None if F_img is None else float(np.median(sampson_distance(F_img, x1, x2)))
    correction = (fit_camera_correction(x1, x2, intrinsics1.K, T1, intrinsics2.K, T2)
                  if fit_correction else None)
    ok, reason = _verdict(med, threshold_px, correction)
    return PairCheck(verdict="ok" if ok else "miscalibrated", reason=reason + note,
                     median_sampson_px=med, median_sampson_image_px=med_img, matches=len(inliers),
                     inliers=int(inliers.sum()), correction=correction, **base)


def _verdict(med: float, threshold_px: float,
             correction: CameraCorrection | None) -> tuple[bool, str]:
    """(ok, reason) from the median Sampson distance and the correction's significant parts."""
    where = "within" if med <= threshold_px else "above"
    reason = (f"matches lie {med:.2f} px from the pose-implied epipolar lines ({where} the "
              f"{threshold_px:g} px threshold)")
    big = [] if correction is None else significant_components(correction)
    if big:
        reason += "; the images show a camera offset of " + ", ".join(big)
    return med <= threshold_px and not big, reason


def significant_components(c: CameraCorrection) -> list[str]:
    """Determined correction components beyond MAX_ROTATION_DEG / MAX_TRANSLATION_MM by more
    than CORRECTION_SIGMAS standard deviations, as short texts."""
    out = []
    for k, axis in enumerate("xyz"):
        rot, rs = c.rotation_deg[k], c.rotation_sigma_deg[k]
        if c.rotation_determined[k] and abs(rot) - MAX_ROTATION_DEG > CORRECTION_SIGMAS * rs:
            out.append(f"{rot:+.2f} deg about camera {axis}")
    for k, axis in enumerate("xyz"):
        tr, ts = c.translation_mm[k], c.translation_sigma_mm[k]
        if c.translation_determined[k] and abs(tr) - MAX_TRANSLATION_MM > CORRECTION_SIGMAS * ts:
            out.append(f"{tr:+.1f} mm along camera {axis}")
    return out


def _inliers(x1: np.ndarray, x2: np.ndarray, method: str):
    """(mask, F or None, note): outliers removed by the image-only F, or by the best homography
    when the matches do not determine F (a flat scene still has pose-implied epipolar lines)."""
    if len(x1) < 8:
        return np.zeros(len(x1), bool), None, ""
    try:
        F, mask = estimate_fundamental(x1, x2, method)
        return mask, F, ""
    except DegenerateError as err:
        log.debug("image-only F failed (%s); rejecting outliers with a homography", err)
    H, mask = cv2.findHomography(x1, x2, cv2.RANSAC,
                                 HOMOGRAPHY_THRESHOLD_FACTOR * DEFAULT_THRESHOLD_PX)
    if H is None:
        return np.zeros(len(x1), bool), None, ""
    return mask.ravel().astype(bool), None, ("; the matches fit one plane, so the image-only F "
                                             "is undetermined")


def _matches(image1, image2, intr1: Intrinsics, intr2: Intrinsics, T1, T2, detector):
    """Matches in undistorted pixel coordinates of both cameras ((N, 2) each)."""
    H = _prewarp(intr1, intr2, T1, T2)
    if H is None and not (intr1.has_distortion or intr2.has_distortion):
        m = match_features(image1, image2, detector)
        return m.x1, m.x2
    u1, valid1 = _undistort(image1, intr1)
    u2, valid2 = _undistort(image2, intr2)
    if H is not None:  # view 2 resampled on view 1's pixel grid: u2w(x) = u2(H x)
        flags = cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP
        u2 = cv2.warpPerspective(u2, H, intr1.size, flags=flags)
        valid2 = cv2.warpPerspective(valid2.astype(np.uint8), H, intr1.size,
                                     flags=cv2.INTER_NEAREST | cv2.WARP_INVERSE_MAP) > 0
        valid2 = cv2.erode(valid2.astype(np.uint8), np.ones((9, 9), np.uint8)).astype(bool)
    m = match_features(u1, u2, detector, mask1=valid1, mask2=valid2)
    return m.x1, (m.x2 if H is None else apply(H, m.x2))


def _prewarp(intr1: Intrinsics, intr2: Intrinsics, T1: np.ndarray,
             T2: np.ndarray) -> np.ndarray | None:
    """Homography view-1 pixel -> view-2 pixel (undistorted) that undoes the recorded turn
    between the views, or None when they turn by less than PREWARP_MIN_ROTATION_DEG.

    It is the homography of the plane facing camera 1 through the point where the two optical
    axes pass closest (a verging pair looks at the scene there), or of the plane at infinity
    (a pure rotation) when the axes do not converge in front of camera 1.
    """
    R = T2[:3, :3].T @ T1[:3, :3]  # camera 1 -> camera 2
    angle = math.degrees(math.acos(min(1.0, max(-1.0, (np.trace(R) - 1) / 2))))
    if angle <= PREWARP_MIN_ROTATION_DEG:
        return None
    t = T2[:3, :3].T @ (T1[:3, 3] - T2[:3, 3])
    depth = _fixation_depth(T1, T2)
    M = R if depth is None else R + np.outer(t, [0.0, 0.0, 1.0 / depth])
    return intr2.K @ M @ np.linalg.inv(intr1.K)


def _fixation_depth(T1: np.ndarray, T2: np.ndarray) -> float | None:
    """Depth along camera 1's axis of the axes' closest approach; None if not in front."""
    a1, a2 = T1[:3, 2], T2[:3, 2]
    w = T1[:3, 3] - T2[:3, 3]
    b = float(a1 @ a2)
    den = 1.0 - b * b
    if den < math.sin(math.radians(PREWARP_MIN_ROTATION_DEG)) ** 2:
        return None  # (nearly) parallel axes
    s = (b * float(a2 @ w) - float(a1 @ w)) / den
    return s if s > 0 else None


def _undistort(image: np.ndarray, intr: Intrinsics) -> tuple[np.ndarray, np.ndarray]:
    """The image without lens distortion (same K) and its validity mask, eroded so features
    keep clear of the fill."""
    if not intr.has_distortion:
        return image, np.ones(image.shape[:2], bool)
    return _remap(image, intr, np.eye(3), intr.K)


def _remap(image: np.ndarray, intr: Intrinsics, R: np.ndarray, K_new: np.ndarray):
    """Undistort ``image`` and rotate it by R (new frame = R @ old frame) into K_new; returns
    the image and a validity mask eroded so that features keep clear of the fill."""
    mx, my = cv2.initUndistortRectifyMap(intr.K, intr.dist, R, K_new, intr.size, cv2.CV_32FC1)
    out = cv2.remap(image, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT)
    valid = (mx >= 0) & (my >= 0) & (mx <= intr.width - 1) & (my <= intr.height - 1)
    valid = cv2.erode(valid.astype(np.uint8), np.ones((9, 9), np.uint8)).astype(bool)
    return out, valid
