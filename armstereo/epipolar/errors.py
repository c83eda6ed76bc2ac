"""Errors of the epipolar package.

Both derive from :class:`armstereo.errors.StereoError`, so the CLI exits with code 6 ("stereo
failed") and prints one line, like every other geometry failure.
"""

from __future__ import annotations

from armstereo.errors import StereoError


class EpipolarError(StereoError):
    """Epipolar geometry cannot be computed from this input (bad shapes, too few matches)."""


class DegenerateError(EpipolarError):
    """The correspondences do not determine a fundamental matrix.

    Raised for fewer than 8 correspondences, points related by one homography (all on a plane,
    or a camera that only rotated), and coincident optical centres in
    :func:`~armstereo.epipolar.fundamental.fundamental_from_poses`.
    """
