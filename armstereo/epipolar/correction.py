"""The small camera offset that best explains why matches miss the pose-implied epipolar lines.

Model: both recorded camera poses share one error, as a wrong hand-eye transform (or a bracket
that slipped) would give: the true poses are ``T_base_cam_i @ D`` with
``D = T_camrecorded_camtrue`` (camera frame: x right, y down, z forward). ``D`` is found by
Levenberg-Marquardt on the signed Sampson distances of the inlier matches, with Huber weights
against the odd bad match and a weak Gaussian prior (:data:`PRIOR_ROTATION_DEG`,
:data:`PRIOR_TRANSLATION_MM`) that keeps directions the pair cannot see at zero.

What one pair can see: with ``X2 = R X1 + t`` the recorded motion, the true one is
``D^-1 (R, t) D``. A camera that only translated (R = I, every armstereo capture) shows the
rotation of D except about the baseline, and none of D's translation (it moves the whole point
cloud rigidly, and bends nothing). Translation shows only through ``(R - I) d``, i.e. when the
views differ by a rotation, and never along the rotation axis. The fit reports each component's
standard deviation; components whose deviation stays near the prior's are "not determined".
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from armstereo.epipolar.projective import homogeneous, skew
from armstereo.transforms import make_T, rotvec_to_matrix

PRIOR_ROTATION_DEG = 5.0
PRIOR_TRANSLATION_MM = 20.0
HUBER_PX = 1.0  # residuals beyond this get linearly growing (not quadratic) weight
DETERMINED_SHARE = 0.25  # determined: standard deviation below this share of the prior's
SIGNIFICANT_SIGMAS = 2.0  # a component is reported when |value| exceeds this many sigmas
MIN_REPORTED_DEG = 0.05
MIN_REPORTED_MM = 0.5
MAX_ITERATIONS = 30
JACOBIAN_STEP = 1e-4  # degrees / millimetres
AXES = ("x", "y", "z")


@dataclass(frozen=True)
class CameraCorrection:
    """``D = T_camrecorded_camtrue``: rotation (rotation vector, deg, camera frame) and
    translation (mm, camera frame), their 1-sigma uncertainties and the median Sampson distance
    (px) of the matches once D is applied."""

    rotation_deg: np.ndarray
    translation_mm: np.ndarray
    rotation_sigma_deg: np.ndarray
    translation_sigma_mm: np.ndarray
    median_sampson_after_px: float

    @property
    def T_camrecorded_camtrue(self) -> np.ndarray:
        """4x4 D (metres): ``T_base_cam_true = T_base_cam_recorded @ D``."""
        return make_T(rotvec_to_matrix(np.radians(self.rotation_deg)),
                      self.translation_mm / 1000.0)

    @property
    def rotation_determined(self) -> np.ndarray:
        """(3,) bool per camera axis: does the pair pin this rotation component down?"""
        return self.rotation_sigma_deg <= DETERMINED_SHARE * PRIOR_ROTATION_DEG

    @property
    def translation_determined(self) -> np.ndarray:
        return self.translation_sigma_mm <= DETERMINED_SHARE * PRIOR_TRANSLATION_MM

    def describe(self) -> list[str]:
        """Plain sentences: what the camera does differently from what the mount says."""
        out = []
        rot, rs, rdet = self.rotation_deg, self.rotation_sigma_deg, self.rotation_determined
        for k, (pos, neg) in enumerate((("up", "down"), ("right", "left"),
                                        ("clockwise", "anticlockwise"))):
            if rdet[k] and abs(rot[k]) >= max(SIGNIFICANT_SIGMAS * rs[k], MIN_REPORTED_DEG):
                way = pos if rot[k] > 0 else neg
                verb = "is rolled" if k == 2 else "looks"
                tail = " (seen from behind the camera)" if k == 2 else ""
                out.append(f"the camera {verb} {abs(rot[k]):.2f} deg further {way}{tail} than "
                           f"the mount says (+-{max(rs[k], 0.01):.2f})")
        tr, ts, tdet = self.translation_mm, self.translation_sigma_mm, self.translation_determined
        for k, (pos, neg) in enumerate((("right", "left"), ("down", "up"),
                                        ("forward", "back"))):
            if tdet[k] and abs(tr[k]) >= max(SIGNIFICANT_SIGMAS * ts[k], MIN_REPORTED_MM):
                way = pos if tr[k] > 0 else neg
                out.append(f"the camera sits {abs(tr[k]):.1f} mm further {way} than the mount "
                           f"says (+-{max(ts[k], 0.1):.1f})")
        hidden = [f"rotation about camera {a}" for a, d in zip(AXES, rdet, strict=True) if not d]
        hidden += [f"translation along camera {a}" for a, d in zip(AXES, tdet, strict=True)
                   if not d]
        if hidden:
            out.append("this pair cannot see: " + ", ".join(hidden))
        return out

    def as_dict(self) -> dict:
        """JSON-ready: degrees and millimetres in the recorded camera frame."""
        return {"rotation_deg": _round(self.rotation_deg, 4),
                "rotation_sigma_deg": _round(self.rotation_sigma_deg, 4),
                "translation_mm": _round(self.translation_mm, 3),
                "translation_sigma_mm": _round(self.translation_sigma_mm, 3),
                "rotation_determined": self.rotation_determined.tolist(),
                "translation_determined": self.translation_determined.tolist(),
                "median_sampson_after_px": round(self.median_sampson_after_px, 4),
                "description": self.describe()}


def _round(v: np.ndarray, digits: int) -> list[float]:
    return [round(float(x), digits) for x in v]


def fit_camera_correction(x1: np.ndarray, x2: np.ndarray, K1: np.ndarray,
                          T_base_cam1: np.ndarray, K2: np.ndarray,
                          T_base_cam2: np.ndarray) -> CameraCorrection:
    """Fit D (see the module doc) to inlier matches ``x1, x2`` ((N, 2) undistorted px) of two
    views with recorded poses ``T_base_cam1/2`` (4x4, metres) and camera matrices K1, K2."""
    h1, h2 = homogeneous(np.asarray(x1, float)), homogeneous(np.asarray(x2, float))
    K1i, K2i = np.linalg.inv(K1), np.linalg.inv(K2)

    def residuals(p: np.ndarray) -> np.ndarray:
        return _signed_sampson(_F(p, K1i, K2i, T_base_cam1, T_base_cam2), h1, h2)

    prior = 1.0 / np.array([PRIOR_ROTATION_DEG] * 3 + [PRIOR_TRANSLATION_MM] * 3)
    p = np.zeros(6)
    lam = 1e-3
    for _ in range(MAX_ITERATIONS):
        r = residuals(p)
        w = _huber_weights(r)
        J = _jacobian(residuals, p, r)
        A = J.T @ (w[:, None] * J) + np.diag(prior ** 2)
        g = J.T @ (w * r) + prior ** 2 * p
        cost = float(np.sum(w * r * r) + np.sum((prior * p) ** 2))
        step = np.linalg.solve(A + lam * np.diag(np.diag(A)), -g)
        r_new = residuals(p + step)
        new_cost = float(np.sum(_huber_weights(r_new) * r_new ** 2)
                         + np.sum((prior * (p + step)) ** 2))
        if new_cost < cost:
            p, lam = p + step, lam / 10.0
            if np.max(np.abs(step)) < 1e-6:
                break
        else:
            lam *= 10.0
    r = residuals(p)
    w = _huber_weights(r)
    J = _jacobian(residuals, p, r)
    dof = max(len(r) - 6, 1)
    s2 = max(float(np.sum(w * r * r)) / dof, 1e-12)
    cov = s2 * np.linalg.inv(J.T @ (w[:, None] * J) + np.diag(prior ** 2 * s2))
    sigma = np.sqrt(np.diag(cov))
    return CameraCorrection(p[:3], p[3:], sigma[:3], sigma[3:], float(np.median(np.abs(r))))


def _F(p: np.ndarray, K1i, K2i, T1: np.ndarray, T2: np.ndarray) -> np.ndarray:
    """Unnormalised F of the poses corrected by p = (rotation vector deg, translation mm);
    the baseline is scaled to unit length so F's sign and size vary smoothly with p."""
    D = make_T(rotvec_to_matrix(np.radians(p[:3])), p[3:] / 1000.0)
    T21 = np.linalg.solve(T2 @ D, T1 @ D)
    t = T21[:3, 3]
    return K2i.T @ skew(t / math.sqrt(float(t @ t))) @ T21[:3, :3] @ K1i


def _signed_sampson(F: np.ndarray, h1: np.ndarray, h2: np.ndarray) -> np.ndarray:
    Fx1 = h1 @ F.T
    Ftx2 = h2 @ F
    num = np.sum(h2 * Fx1, axis=1)
    return num / np.sqrt(Fx1[:, 0] ** 2 + Fx1[:, 1] ** 2 + Ftx2[:, 0] ** 2 + Ftx2[:, 1] ** 2)


def _huber_weights(r: np.ndarray) -> np.ndarray:
    a = np.abs(r)
    return np.where(a <= HUBER_PX, 1.0, HUBER_PX / np.maximum(a, 1e-300))


def _jacobian(fun, p: np.ndarray, r0: np.ndarray) -> np.ndarray:
    """Forward-difference Jacobian (N, 6)."""
    J = np.empty((len(r0), len(p)))
    for k in range(len(p)):
        q = p.copy()
        q[k] += JACOBIAN_STEP
        J[:, k] = (fun(q) - r0) / JACOBIAN_STEP
    return J
