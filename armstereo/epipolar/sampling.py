"""MLESAC, MAPSAC and LMedS: random 7-point samples scored by a robust cost (Torr & Zisserman).

OpenCV has neither score, so the sample-and-score loop lives here; the minimal solver is
OpenCV's 7-point algorithm (up to three real solutions per sample).

* ``mapsac`` scores a hypothesis by ``sum(min(e_i^2, T^2))`` over the Sampson distances
  ``e_i``: the truncated quadratic of MSAC, which is how Torr's MAPSAC is used in practice.
* ``lmeds`` scores it by the median squared Sampson distance (least median of squares; the
  loop of :mod:`armstereo.epipolar.lmeds`).
* ``mlesac`` scores it by the negative log-likelihood of a mixture: inliers Gaussian with
  sigma = ``T / INLIER_SIGMAS`` (px), outliers uniform over the image span ``v`` (px); the
  inlier share ``gamma`` is re-estimated per hypothesis by a few EM steps.

Each new best hypothesis is locally optimised (LO-RANSAC): refitted on the points within
``2 T`` by the normalised 8-point algorithm while that lowers the cost. The winner is refitted
once more until its inlier set stops changing (at most :data:`REFIT_ROUNDS` times). Sampling
stops when the usual RANSAC bound says a clean sample has been drawn with probability
``confidence``, but not before :data:`MIN_SAMPLES` samples.
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from armstereo.epipolar.errors import DegenerateError
from armstereo.epipolar.linear import eight_point, refit_on_inliers
from armstereo.epipolar.metrics import sampson_homogeneous
from armstereo.epipolar.projective import homogeneous

SAMPLE_SIZE = 7
INLIER_SIGMAS = 1.96  # T is the 95 % bound of a Gaussian inlier residual
EM_STEPS = 5
REFIT_ROUNDS = 3
LO_ROUNDS = 5
LO_THRESHOLD_FACTOR = 2.0
MIN_SAMPLES = 100  # RANSAC's bound assumes every clean sample gives a good F; noisy ones don't
MIN_LO_POINTS = 16  # the local refit needs clearly more than the 8 points of a minimal fit
COSTS = ("mlesac", "mapsac", "lmeds")


def consensus(x1: np.ndarray, x2: np.ndarray, cost: str, *, threshold: float,
              confidence: float, max_iters: int, seed: int = 0) -> np.ndarray:
    """Best F of ``(N, 2)`` pixel pairs under ``cost`` (one of :data:`COSTS`).

    ``threshold`` (px) is the inlier bound T on the Sampson distance. Raises DegenerateError
    when no sample yields a matrix or fewer than 8 points support the best one.
    """
    if cost not in COSTS:
        raise ValueError(f"cost must be one of {COSTS}, got {cost!r}")
    rng = np.random.default_rng(seed)
    n = len(x1)
    span = _span(x2)
    h1, h2 = homogeneous(x1), homogeneous(x2)
    best_F, best_cost, most_inliers = None, np.inf, 0
    needed, it = max_iters, 0
    while it < min(max(needed, MIN_SAMPLES), max_iters):
        it += 1
        sample = rng.choice(n, SAMPLE_SIZE, replace=False)
        for F in _seven_point(x1[sample], x2[sample]):
            e = sampson_homogeneous(F, h1, h2)
            c = _score(e, cost, threshold, span)
            if c < best_cost:
                F, c, e = _local_optimisation(F, c, e, x1, x2, h1, h2, cost, threshold, span)
                best_F, best_cost = F, c
            inliers = int(np.count_nonzero(e < threshold))
            if inliers > most_inliers:  # the stopping bound uses the best inlier share seen
                most_inliers = inliers
                needed = _iterations_needed(most_inliers / n, confidence)
    if best_F is None:
        raise DegenerateError(f"no 7-point sample of the {n} correspondences gave a fundamental "
                              "matrix")
    return refit_on_inliers(best_F, x1, x2, threshold, rounds=REFIT_ROUNDS)


def _local_optimisation(F, c, e, x1, x2, h1, h2, cost: str, threshold: float, span: float):
    """LO-RANSAC step for a new best hypothesis: refit F by the 8-point algorithm on the points
    within LO_THRESHOLD_FACTOR thresholds while that lowers the cost (a 7-point sample of noisy
    points is rarely the best F)."""
    for _ in range(LO_ROUNDS):
        mask = e < LO_THRESHOLD_FACTOR * threshold  # wider: a rough model misses good points
        if mask.sum() < MIN_LO_POINTS:
            break
        try:
            F_new = eight_point(x1[mask], x2[mask])
        except DegenerateError:
            break
        e_new = sampson_homogeneous(F_new, h1, h2)
        c_new = _score(e_new, cost, threshold, span)
        if c_new >= c:
            break
        F, c, e = F_new, c_new, e_new
    return F, c, e


def _seven_point(x1: np.ndarray, x2: np.ndarray) -> list[np.ndarray]:
    F, _ = cv2.findFundamentalMat(x1, x2, cv2.FM_7POINT)
    if F is None:
        return []
    return [F[3 * k:3 * k + 3] for k in range(F.shape[0] // 3)]


def _score(e: np.ndarray, cost: str, threshold: float, span: float) -> float:
    if cost == "lmeds":  # least median of squares: no threshold in the score
        return float(np.median(e * e))
    if cost == "mapsac":
        return float(np.sum(np.minimum(e * e, threshold * threshold)))
    sigma = threshold / INLIER_SIGMAS
    p_in = np.exp(-0.5 * (e / sigma) ** 2) / (math.sqrt(2 * math.pi) * sigma)
    p_out = 1.0 / span
    gamma = 0.5
    for _ in range(EM_STEPS):
        w = gamma * p_in / (gamma * p_in + (1 - gamma) * p_out)
        gamma = min(max(float(np.sum(w)) / len(w), 1e-6), 1 - 1e-6)
    return float(-np.sum(np.log(gamma * p_in + (1 - gamma) * p_out)))


def _span(x: np.ndarray) -> float:
    """Range (px) over which an outlier's residual is taken as uniform: the points' diagonal."""
    return float(max(np.hypot(*np.ptp(x, axis=0)), 1.0))


def _iterations_needed(inlier_share: float, confidence: float) -> int:
    """RANSAC's bound: samples needed to draw one all-inlier 7-point sample."""
    clean = inlier_share ** SAMPLE_SIZE
    if clean <= 0:
        return np.iinfo(np.int32).max
    if clean >= 1:
        return 1
    return int(math.ceil(math.log(1 - confidence) / math.log(1 - clean)))
