"""What a rectification produces: the rectified pair's geometry and images.

:class:`StereoGeometry` (metres and pixels, what triangulation needs), :class:`Rectification`
(the homographies and projection matrices) and :class:`RectifiedPair` (images, validity masks,
maps and where they came from), made by :mod:`.rectify`; conventions as there
(docs/rectification.md).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from armstereo.camera_model import Intrinsics
from armstereo.errors import StereoError
from armstereo.transforms import make_T


class Rectification(NamedTuple):
    """Rectifying homographies (original pixel -> rectified pixel) and rectified 3x4 PPMs."""

    H1: np.ndarray
    H2: np.ndarray
    P1: np.ndarray
    P2: np.ndarray


@dataclass(frozen=True)
class StereoGeometry:
    """A rectified pair in metres and pixels; frame of reference: rectified left camera.

    ``R_rect`` rotates base-frame vectors into the rectified cameras' frame; ``c_left`` and
    ``c_right`` are the optical centres in ``base``. Disparity ``d = x_left - x_right`` relates to
    depth by ``Z = fx * baseline / (d - disparity_offset)``.
    """

    fx: float
    fy: float
    cx_left: float
    cx_right: float
    cy: float
    baseline: float
    size: tuple[int, int]
    R_rect: np.ndarray
    c_left: np.ndarray
    c_right: np.ndarray

    @property
    def disparity_offset(self) -> float:
        """``cx_left - cx_right``: the disparity of a point at infinity (pixels)."""
        return self.cx_left - self.cx_right

    @property
    def K_left(self) -> np.ndarray:
        return np.array([[self.fx, 0, self.cx_left], [0, self.fy, self.cy], [0, 0, 1.0]])

    @property
    def T_base_rectleft(self) -> np.ndarray:
        """Pose of the rectified left camera in ``base`` (4x4)."""
        return make_T(self.R_rect.T, self.c_left)

    @property
    def Q(self) -> np.ndarray:
        """4x4 reprojection: ``Q @ [u, v, d, 1]`` ~ homogeneous point in the rectified-left frame.

        OpenCV's form with Tx = -baseline, its second row generalised to fx != fy.
        """
        a = self.fx / self.fy
        b = self.baseline
        return np.array([[1.0, 0, 0, -self.cx_left],
                         [0, a, 0, -self.cy * a],
                         [0, 0, 0, self.fx],
                         [0, 0, 1.0 / b, -self.disparity_offset / b]])

    def disparity_window(self, near: float, far: float) -> tuple[float, float]:
        """Disparities ``(d_min, d_max)`` (pixels) of depths ``far`` and ``near`` (metres)."""
        if not 0 < near < far:
            raise StereoError(f"need 0 < near < far, got near={near} far={far}")
        fb = self.fx * self.baseline
        return fb / far + self.disparity_offset, fb / near + self.disparity_offset


@dataclass(frozen=True)
class RectifiedPair:
    """Rectified images, validity masks and geometry of a pair, plus where they came from.

    ``left``/``right`` are the rectified images (BGR or grey uint8, as given); masks are True
    where the pixel was sampled inside the source image. ``swapped`` is True when the second
    input image became the left one. ``rectification`` holds H/P for (left, right) in that order;
    ``left_intrinsics``/``T_base_left_camera`` describe the original (unrectified) left camera.
    ``maps_left``/``maps_right`` are the float32 ``cv2.remap`` maps (rectified pixel -> source).
    """

    left: np.ndarray
    right: np.ndarray
    left_mask: np.ndarray
    right_mask: np.ndarray
    geometry: StereoGeometry
    rectification: Rectification
    swapped: bool
    left_intrinsics: Intrinsics
    T_base_left_camera: np.ndarray
    maps_left: tuple[np.ndarray, np.ndarray]
    maps_right: tuple[np.ndarray, np.ndarray]
    baseline_angle_deg: float  # angle between baseline and the left camera's optical axis
    rotation_deg: float  # in-plane rotation the rectification applies to the left image

    @property
    def size(self) -> tuple[int, int]:
        """Rectified canvas (width, height)."""
        return self.geometry.size

    @property
    def baseline(self) -> float:
        return self.geometry.baseline

    @property
    def Q(self) -> np.ndarray:
        return self.geometry.Q

    @property
    def R_left_cv(self) -> np.ndarray:
        """Rotation from the original left camera frame to the rectified left camera frame."""
        return self.geometry.R_rect @ self.T_base_left_camera[:3, :3]
