"""What kind of motion separates two camera poses, and is it fit for two-view stereo?

Camera poses are 4x4 ``T_base_cam`` (OpenCV camera frame in ``base``, metres). The kinds:

* ``rotation_only``: the optical centres are less than ``min_baseline`` apart. There is no
  epipolar geometry; depth cannot be triangulated.
* ``forward``: the baseline lies within :data:`FORWARD_CONE_DEG` of either optical axis. The
  epipoles sit near the image centres, where rectification degenerates and depth is poor.
* ``lateral``: the baseline lies within :data:`LATERAL_CONE_DEG` of both image planes and the
  cameras turn by less than :data:`LATERAL_MAX_ROTATION_DEG`: the textbook stereo rig.
* ``general``: anything else.

An epipole (the other camera's centre seen in an image) inside the image is reported for any
kind: rectification maps it to infinity and the images stretch without bound around it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from armstereo.camera_model import Intrinsics
from armstereo.epipolar.projective import check_pose
from armstereo.errors import PreflightError

KINDS = ("rotation_only", "lateral", "forward", "general")
MIN_BASELINE_M = 0.005  # below this the pair counts as a pure rotation
FORWARD_CONE_DEG = 30.0
LATERAL_CONE_DEG = 15.0
LATERAL_MAX_ROTATION_DEG = 5.0
MAX_EPIPOLE_PX = 1e6  # farther epipoles are reported as "at infinity" (None)


@dataclass(frozen=True)
class MotionReport:
    """Relative motion of camera 2 with respect to camera 1.

    ``baseline_m``: distance of the optical centres; ``rotation_deg``: angle of the relative
    rotation; ``baseline_angle_deg``: angle between the baseline and camera 1's optical axis
    (0 = straight ahead, 90 = sideways); ``direction_cam1``: unit baseline ``c2 - c1`` in camera
    1's frame (zeros for a zero baseline). ``epipole1_px``/``epipole2_px``: the epipole in image
    1 (camera 2's centre) and image 2 (camera 1's centre), None when it is at infinity or no
    intrinsics were given; ``epipole_in_image`` is True when either lies inside its image.
    """

    kind: str
    baseline_m: float
    rotation_deg: float
    baseline_angle_deg: float
    direction_cam1: np.ndarray
    epipole1_px: tuple[float, float] | None = None
    epipole2_px: tuple[float, float] | None = None
    epipole_in_image: bool = False
    warnings: list[str] = field(default_factory=list)

    def as_dict(self) -> dict:
        """JSON-ready summary (angles in degrees, lengths in metres, epipoles in px)."""
        return {"kind": self.kind, "baseline_m": round(self.baseline_m, 6),
                "rotation_deg": round(self.rotation_deg, 4),
                "baseline_angle_deg": round(self.baseline_angle_deg, 3),
                "epipole1_px": _rounded(self.epipole1_px),
                "epipole2_px": _rounded(self.epipole2_px),
                "epipole_in_image": self.epipole_in_image, "warnings": list(self.warnings)}


def _rounded(p: tuple[float, float] | None) -> list[float] | None:
    return None if p is None else [round(p[0], 2), round(p[1], 2)]


def classify_motion(T_base_cam1: np.ndarray, T_base_cam2: np.ndarray, *,
                    intrinsics1: Intrinsics | None = None,
                    intrinsics2: Intrinsics | None = None,
                    min_baseline: float = MIN_BASELINE_M) -> MotionReport:
    """Classify the motion between two camera poses (see the module doc for the kinds).

    Epipoles are computed when intrinsics are given (``intrinsics2`` defaults to
    ``intrinsics1``). Raises EpipolarError for a pose that is not a rigid transform.
    """
    T1, T2 = check_pose(T_base_cam1, "T_base_cam1"), check_pose(T_base_cam2, "T_base_cam2")
    R1, R2 = T1[:3, :3], T2[:3, :3]
    b = T2[:3, 3] - T1[:3, 3]
    baseline = float(np.linalg.norm(b))
    cos_rot = (np.trace(R1.T @ R2) - 1.0) / 2.0
    rotation = math.degrees(math.acos(min(1.0, max(-1.0, cos_rot))))
    if baseline < min_baseline:
        return MotionReport("rotation_only", baseline, rotation, float("nan"), np.zeros(3),
                            warnings=[f"the optical centres are {baseline * 1000:.1f} mm apart "
                                      f"(< {min_baseline * 1000:.1f} mm): a rotation without "
                                      "baseline gives no depth"])
    d1 = R1.T @ b / baseline
    angle1 = _axis_angle(d1)
    angle2 = _axis_angle(R2.T @ b / baseline)
    if min(angle1, angle2) < FORWARD_CONE_DEG:
        kind = "forward"
    elif min(angle1, angle2) > 90.0 - LATERAL_CONE_DEG and rotation < LATERAL_MAX_ROTATION_DEG:
        kind = "lateral"
    else:
        kind = "general"
    intrinsics2 = intrinsics2 or intrinsics1
    e1 = _epipole(intrinsics1, R1.T @ (T2[:3, 3] - T1[:3, 3]))
    e2 = _epipole(intrinsics2, R2.T @ (T1[:3, 3] - T2[:3, 3]))
    inside = [_inside(e, intr) for e, intr in ((e1, intrinsics1), (e2, intrinsics2))]
    warnings = [f"the epipole lies inside image {k + 1} at ({e[0]:.0f}, {e[1]:.0f}) px: "
                "rectification degenerates around it; move the camera more sideways"
                for k, (e, ok) in enumerate(zip((e1, e2), inside, strict=True)) if ok]
    if kind == "forward" and not warnings:
        warnings.append(f"the camera moves along its optical axis (baseline "
                        f"{min(angle1, angle2):.0f} deg from it): depth is poorly conditioned")
    return MotionReport(kind, baseline, rotation, angle1, d1, e1, e2, any(inside), warnings)


def _axis_angle(d: np.ndarray) -> float:
    """Angle (deg, 0..90) between the unit direction d and the optical axis line (+-z)."""
    return math.degrees(math.acos(min(1.0, abs(float(d[2])))))


def _epipole(intr: Intrinsics | None, c_other: np.ndarray) -> tuple[float, float] | None:
    """Pixel of the other centre (camera frame), in front or behind; None at infinity."""
    if intr is None or c_other[2] == 0:
        return None
    p = intr.K @ (c_other / c_other[2])
    if not np.all(np.abs(p[:2]) < MAX_EPIPOLE_PX):
        return None
    return float(p[0]), float(p[1])


def _inside(e: tuple[float, float] | None, intr: Intrinsics | None) -> bool:
    if e is None or intr is None:
        return False
    return -0.5 <= e[0] <= intr.width - 0.5 and -0.5 <= e[1] <= intr.height - 0.5


def require_stereo_motion(T_base_cam1: np.ndarray, T_base_cam2: np.ndarray,
                          intrinsics: Intrinsics, *,
                          min_baseline: float = MIN_BASELINE_M) -> MotionReport:
    """Capture pre-flight guard for one planned pair (poses in ``base``, metres).

    Raises PreflightError when the views would differ by a rotation only (optical centres
    closer than ``min_baseline``); otherwise returns the report, whose ``warnings`` (an epipole
    inside the image, a forward motion) the caller shows before moving.
    """
    report = classify_motion(T_base_cam1, T_base_cam2, intrinsics1=intrinsics,
                             min_baseline=min_baseline)
    if report.kind == "rotation_only":
        raise PreflightError(f"planned pair is a pure rotation: {report.warnings[0]}")
    return report
