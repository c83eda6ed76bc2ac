"""Pinhole camera intrinsics with OpenCV distortion (camera frame: x right, y down, z forward)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from armstereo.errors import ConfigError


@dataclass(frozen=True)
class Intrinsics:
    """Image size in pixels, 3x3 camera matrix K and OpenCV distortion coefficients.

    ``dist`` follows OpenCV's order (k1, k2, p1, p2[, k3[, k4, k5, k6]]); all zeros means an
    ideal pinhole. Foxglove calls this model ``plumb_bob`` (5) or ``rational_polynomial`` (8).
    """

    width: int
    height: int
    K: np.ndarray
    dist: np.ndarray = field(default_factory=lambda: np.zeros(5))

    def __post_init__(self) -> None:
        K = np.asarray(self.K, dtype=float).reshape(3, 3)
        dist = np.asarray(self.dist, dtype=float).reshape(-1)
        object.__setattr__(self, "K", K)
        object.__setattr__(self, "dist", dist)
        if self.width <= 0 or self.height <= 0:
            raise ConfigError(f"image size must be positive, got {self.width}x{self.height}")
        if not np.all(np.isfinite(K)) or not np.all(np.isfinite(dist)):
            raise ConfigError("camera matrix K and distortion must be finite numbers")
        if K[0, 0] <= 0 or K[1, 1] <= 0 or K[2, 2] != 1.0 or K[1, 0] or K[2, 0] or K[2, 1]:
            raise ConfigError("camera matrix K must be [[fx, s, cx], [0, fy, cy], [0, 0, 1]] "
                              f"with fx, fy > 0, got {K.round(6).tolist()}")
        if dist.size not in (4, 5, 8, 12, 14):
            raise ConfigError(f"distortion needs 4, 5, 8, 12 or 14 coefficients, not {dist.size}")

    @property
    def fx(self) -> float:
        return float(self.K[0, 0])

    @property
    def fy(self) -> float:
        return float(self.K[1, 1])

    @property
    def cx(self) -> float:
        return float(self.K[0, 2])

    @property
    def cy(self) -> float:
        return float(self.K[1, 2])

    @property
    def has_distortion(self) -> bool:
        return bool(np.any(self.dist != 0))

    @property
    def size(self) -> tuple[int, int]:
        """(width, height), OpenCV's order."""
        return (self.width, self.height)

    def scaled(self, width: int, height: int) -> Intrinsics:
        """The same camera delivering ``width`` x ``height`` images (a binned or scaled mode of
        the same sensor): K scaled about pixel corners, distortion unchanged (it acts on
        normalised coordinates). ConfigError if the aspect ratio differs by more than a pixel."""
        sx, sy = width / self.width, height / self.height
        if abs(sx * self.height - height) > 1.0 or abs(sy * self.width - width) > 1.0:
            raise ConfigError(f"{width}x{height} does not have the aspect ratio of the "
                              f"calibrated {self.width}x{self.height}; calibrate at that mode")
        K = self.K.copy()
        K[0, :] *= sx
        K[1, :] *= sy
        # pixel centres sit at integer coordinates: (c + 0.5) scales, c does not
        K[0, 2] = (self.cx + 0.5) * sx - 0.5
        K[1, 2] = (self.cy + 0.5) * sy - 0.5
        return Intrinsics(width, height, K, self.dist.copy())

    def projection(self, T_camera_world: np.ndarray) -> np.ndarray:
        """3x4 projection matrix K [R | t] for a camera whose pose is given as T_camera_world."""
        return self.K @ np.asarray(T_camera_world, dtype=float)[:3, :]
