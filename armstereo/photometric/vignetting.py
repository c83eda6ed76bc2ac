"""A lens's vignetting: how much darker the image gets away from its optical centre.

The model is the radial polynomial of photometric calibration for direct visual odometry
(Engel, Usenko, Cremers, "A Photometrically Calibrated Benchmark For Monocular Visual
Odometry", 2016)::

    V(x) = 1 + k1 r^2 + k2 r^4 + k3 r^6,    r = |x - center| / R

with ``x`` a pixel of the raw (distorted) image, ``center`` the fall-off's centre (px; the
principal point for a rotationally symmetric lens) and ``R`` the half-diagonal of the image,
``sqrt(W^2 + H^2) / 2`` px, so the coefficients of cameras of one family compare. An image
pixel is ``V(x)`` times what a lens without vignetting would have delivered; dividing by
``V`` removes it. A mount file carries it as an optional section::

    [vignetting]
    # relative brightness V = 1 + k1 r^2 + k2 r^4 + k3 r^6, r = distance from center / half-diagonal
    center = [321.7, 245.0]
    k = [-0.17, -0.08, 0.0]
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

from armstereo.errors import ConfigError

MIN_GAIN = 0.2  # a model darker than this anywhere in the image is not a lens's vignetting


@dataclass(frozen=True)
class Vignetting:
    """The fall-off ``V`` of a ``width`` x ``height`` camera (module doc): ``center`` (px, raw
    image), ``k`` = (k1, k2, k3) on the squared distance over the half-diagonal."""

    width: int
    height: int
    center: tuple[float, float]
    k: tuple[float, float, float]

    def __post_init__(self) -> None:
        if not (isinstance(self.width, int) and isinstance(self.height, int)
                and self.width > 0 and self.height > 0):
            raise ConfigError(f"vignetting image size must be positive whole pixels, got "
                              f"{self.width}x{self.height}")
        center = tuple(float(v) for v in self.center)
        k = tuple(float(v) for v in self.k)
        if len(center) != 2 or len(k) != 3 or not all(map(math.isfinite, center + k)):
            raise ConfigError(f"vignetting needs center = [cx, cy] and k = [k1, k2, k3], finite, "
                              f"got {list(self.center)}, {list(self.k)}")
        object.__setattr__(self, "center", center)
        object.__setattr__(self, "k", k)
        if self.min_gain() < MIN_GAIN or self.max_gain() > 1.0 / MIN_GAIN:
            raise ConfigError(f"vignetting k = {list(k)} makes the image "
                              f"{self.min_gain():.2f}-{self.max_gain():.2f} times as bright; a "
                              f"lens's fall-off stays within {MIN_GAIN:g}-{1 / MIN_GAIN:g}")

    @property
    def radius(self) -> float:
        """R: the half-diagonal of the image (px)."""
        return math.hypot(self.width, self.height) / 2.0

    def gain(self, u: np.ndarray, v: np.ndarray) -> np.ndarray:
        """V at raw-image pixels (u, v) (arrays of one shape, px), float64."""
        r2 = ((np.asarray(u, float) - self.center[0]) ** 2
              + (np.asarray(v, float) - self.center[1]) ** 2) / self.radius ** 2
        return 1.0 + r2 * (self.k[0] + r2 * (self.k[1] + r2 * self.k[2]))

    def gain_map(self) -> np.ndarray:
        """V of every pixel (H, W) float32 (cached per model)."""
        return _gain_map(self)

    def corner_gains(self) -> np.ndarray:
        """V at the four image corners (top-left, top-right, bottom-right, bottom-left)."""
        u = np.array([0.0, self.width - 1.0, self.width - 1.0, 0.0])
        v = np.array([0.0, 0.0, self.height - 1.0, self.height - 1.0])
        return self.gain(u, v)

    def min_gain(self) -> float:
        return float(self._extremes()[0])

    def max_gain(self) -> float:
        return float(self._extremes()[1])

    def _extremes(self) -> tuple[float, float]:
        # V depends on r only: sample r from 0 to the farthest corner.
        cx, cy = self.center
        far = max(math.hypot(x - cx, y - cy) for x in (0, self.width - 1)
                  for y in (0, self.height - 1))
        r = np.linspace(0.0, far, 257)
        g = self.gain(self.center[0] + r, np.full_like(r, self.center[1]))
        return float(g.min()), float(g.max())

    def as_dict(self) -> dict:
        """JSON-ready: ``{"center": [cx, cy], "k": [k1, k2, k3], "corner_gain": [...]}``."""
        return {"center": list(self.center), "k": list(self.k),
                "corner_gain": [round(float(g), 4) for g in self.corner_gains()]}

    def toml_lines(self) -> list[str]:
        """The mount file's ``[vignetting]`` section (numbers round-trip exactly)."""
        return ["[vignetting]",
                "# relative brightness V = 1 + k1 r^2 + k2 r^4 + k3 r^6, r = distance from "
                "center / half-diagonal",
                f"center = [{', '.join(repr(v) for v in self.center)}]",
                f"k = [{', '.join(repr(v) for v in self.k)}]", ""]

    @classmethod
    def from_dict(cls, doc: dict, width: int, height: int) -> Vignetting:
        """From a mount file's parsed ``[vignetting]`` table, for a ``width`` x ``height``
        camera (ConfigError naming the bad entry)."""
        if not isinstance(doc, dict) or "k" not in doc:
            raise ConfigError("vignetting section needs k = [k1, k2, k3] (and center = [cx, cy])")
        center = doc.get("center", [(width - 1) / 2.0, (height - 1) / 2.0])
        try:
            center, k = [float(v) for v in center], [float(v) for v in doc["k"]]
        except (TypeError, ValueError):
            raise ConfigError(f"vignetting center and k must be numbers, got "
                              f"{doc.get('center')!r}, {doc.get('k')!r}") from None
        k = (k + [0.0, 0.0, 0.0])[:3] if len(k) <= 3 else k
        return cls(width, height, tuple(center), tuple(k))


@functools.lru_cache(maxsize=8)
def _gain_map(model: Vignetting) -> np.ndarray:
    v, u = np.mgrid[0:model.height, 0:model.width]
    return model.gain(u, v).astype(np.float32)


def devignette(image: np.ndarray, model: Vignetting) -> np.ndarray:
    """``image`` (H, W) or (H, W, 3) uint8 with the fall-off divided out, uint8 (values that
    would exceed 255 saturate, as the sensor would have). ConfigError if the sizes differ."""
    h, w = image.shape[:2]
    if (w, h) != (model.width, model.height):
        raise ConfigError(f"the vignetting model is for {model.width}x{model.height} images, "
                          f"this image is {w}x{h}")
    gain = model.gain_map()
    out = image.astype(np.float32) / (gain[..., None] if image.ndim == 3 else gain)
    return np.clip(np.rint(out), 0, 255).astype(np.uint8)
