"""Epipolar geometry from the images: an independent witness of the recorded poses.

Modules (each with one job):

* :mod:`~armstereo.epipolar.features`: Harris + NCC, SIFT and ORB matches.
* :mod:`~armstereo.epipolar.fundamental`: ``estimate_fundamental(x1, x2, method)`` and
  ``fundamental_from_poses(K1, K2, T_base_cam1, T_base_cam2)``; degeneracy checks.
* :mod:`~armstereo.epipolar.linear`: the normalised 8-point algorithm and the inlier refit
  every estimator shares.
* :mod:`~armstereo.epipolar.sampling`, :mod:`~armstereo.epipolar.gold`: MLESAC/MAPSAC and the
  Gold Standard, which OpenCV lacks.
* :mod:`~armstereo.epipolar.metrics`: Sampson, symmetric epipolar and reprojection errors.
* :mod:`~armstereo.epipolar.motion`: what kind of motion separates two poses.
* :mod:`~armstereo.epipolar.selfcheck` + :mod:`~armstereo.epipolar.correction`: per-pair
  verdict ``ok``/``miscalibrated`` and the camera offset that explains the residual.
* :mod:`~armstereo.epipolar.uncalibrated`: reconstruction from two photographs without poses.
* :mod:`~armstereo.epipolar.study`: the camera-motion study of the estimators.

Errors derive from :class:`armstereo.errors.StereoError` (CLI exit code 6).
"""

from armstereo.epipolar.errors import DegenerateError, EpipolarError
from armstereo.epipolar.features import DETECTORS, Matches, match_features
from armstereo.epipolar.fundamental import METHODS, estimate_fundamental, fundamental_from_poses
from armstereo.epipolar.metrics import (
    reprojection_error,
    sampson_distance,
    symmetric_epipolar_distance,
)
from armstereo.epipolar.motion import MotionReport, classify_motion

__all__ = [
    "DETECTORS", "METHODS", "DegenerateError", "EpipolarError", "Matches", "MotionReport",
    "classify_motion", "estimate_fundamental", "fundamental_from_poses", "match_features",
    "reprojection_error", "sampson_distance", "symmetric_epipolar_distance",
]
