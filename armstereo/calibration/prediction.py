"""The predicted hand-eye error: what the report's ``quality.predicted_error`` means.

The hand-eye error is a 3D vector for the translation and one for the rotation; the report
predicts the **expected magnitude** of each, ``E|e|`` for ``e ~ N(0, C)`` with ``C`` the 3x3
covariance of the estimate. That is the number a single calibration's true error scatters
about: for the realistic mock cell, whose translation error lies mostly along the optical
axis, a correct prediction is within a factor of two of the true error on about 80 % of the
cells (an error along one axis is a half-normal draw: a fifth of the time below half or above
twice its mean), 87 % for the rotation (bench/results/calibration_prediction.md). The
covariance's RMS, ``sqrt(trace C)``, and per-axis sigmas are reported beside it.

``C`` comes from the joint refinement (:mod:`armstereo.calibration.refine`): the inverse of
the whitened normal equations with the corner noise and the arm's per-view pose error both
estimated from the data, marginalised over the board pose, the board's shape and the
intrinsics. On the realistic cell its whitened true errors have unit variance per axis
(seeds 0-29). A leave-one-out (jackknife) spread over ten views is itself a noisy estimate
(ten draws per axis) and, on the same cells, 1.3x too pessimistic for the rotation on
average; it remains the prediction only for a closed-form hand-eye (chosen when the arm's
poses limit the result, :mod:`armstereo.calibration.selection`), which has no covariance of
its own.
"""

from __future__ import annotations

import math

import numpy as np

_U = np.linspace(-50.0, 50.0, 2001)  # log-t grid of the integral in expected_norm


def expected_norm(cov: np.ndarray) -> float:
    """``E|e|`` for ``e ~ N(0, cov)`` (3x3, any units), to 1e-6 relative.

    With ``sqrt(q) = 1 / (2 sqrt(pi)) * int_0^inf (1 - exp(-q t)) t^(-3/2) dt`` and the Gaussian's
    ``E exp(-t |e|^2) = prod_i (1 + 2 lam_i t)^(-1/2)`` (lam: the eigenvalues of ``cov``),
    ``E|e|`` is a one-dimensional integral, taken by the trapezoid rule in ``u = log t``
    (its integrand decays like ``exp(-|u| / 2)`` on both sides).
    """
    lam = np.clip(np.linalg.eigvalsh(np.asarray(cov, float)), 0.0, None)
    top = float(lam.max())
    if top <= 0.0:
        return 0.0
    t = np.exp(_U)[:, None]
    g = 1.0 - np.prod(1.0 / np.sqrt(1.0 + 2.0 * (lam / top)[None, :] * t), axis=1)
    f = g / np.sqrt(t[:, 0])  # (1 - E exp(-t q)) t^(-3/2) dt, dt = t du
    du = _U[1] - _U[0]
    integral = du * (float(np.sum(f)) - 0.5 * float(f[0] + f[-1]))
    return math.sqrt(top) * integral / (2.0 * math.sqrt(math.pi))


def predicted_error(cov_X: np.ndarray, basis: str) -> dict:
    """``quality.predicted_error`` from the 6x6 covariance of X's chart (rotation vector rad,
    translation m; camera frame): expected magnitudes, RMS and per-axis sigmas (module doc)."""
    C = np.asarray(cov_X, float)
    Cr, Ct = C[:3, :3], C[3:, 3:]
    return {
        "translation_m": expected_norm(Ct),
        "rotation_deg": math.degrees(expected_norm(Cr)),
        "rms_translation_m": math.sqrt(max(float(np.trace(Ct)), 0.0)),
        "rms_rotation_deg": math.degrees(math.sqrt(max(float(np.trace(Cr)), 0.0))),
        "translation_sigma_m": np.sqrt(np.clip(np.diag(Ct), 0.0, None)).tolist(),
        "rotation_sigma_deg": np.degrees(np.sqrt(np.clip(np.diag(Cr), 0.0, None))).tolist(),
        "quantity": "expected magnitude E|e| of the hand-eye error (translation, rotation); "
                    "rms_*: sqrt(trace) of its covariance; sigmas per camera axis",
        "basis": basis,
    }


def jackknife_covariance(translation_se_m: np.ndarray, rotation_se_deg: np.ndarray
                         ) -> np.ndarray:
    """A 6x6 chart covariance (rotation rad, translation m) from per-axis jackknife standard
    errors (their correlations are not kept)."""
    return np.diag(np.r_[np.radians(rotation_se_deg), translation_se_m] ** 2)
