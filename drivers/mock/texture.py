"""Textures of the mock scenes: colour as a function of where a ray hits a surface.

A :class:`Texture` is defined on 3D *base* coordinates (metres), so the same surface point has
the same colour from every viewpoint (what stereo assumes): a band-limited sum of sinusoids
squashed for contrast, blobs of a few millimetres, never per-pixel white noise, which breaks the
Birchfield-Tomasi cost (docs/birchfield-tomasi.md §9.1). A :class:`SurfaceTexture` is defined
on a primitive's surface coordinates instead (:meth:`drivers.mock.primitives.Primitive.
surface_coords`); :class:`PhotoTexture` maps a photograph that way (see ``drivers/mock/desk.py``).
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from collections.abc import Sequence

import cv2
import numpy as np

from armstereo.errors import ConfigError


class Texture:
    """Band-limited solid texture: colour as a function of a 3D point (metres, base frame).

    ``s(p) = sum_k sin(w_k . (p - anchor) + phi_k)`` over ``components`` directions spread
    evenly over the sphere (randomly rotated, so every surface orientation sees an isotropic
    pattern) with wavelengths log-spaced in [``min_wavelength``, ``max_wavelength``] and
    shuffled; ``s`` is normalised and squashed by a sigmoid of gain ``contrast`` into a blend of
    ``dark_bgr`` and ``light_bgr``. Deterministic for a given ``seed``. Features (half a
    wavelength) are ``min_wavelength / 2`` and up.
    """

    def __init__(self, dark_bgr: Sequence[float], light_bgr: Sequence[float], *,
                 min_wavelength: float = 0.008, max_wavelength: float = 0.022,
                 components: int = 16, contrast: float = 2.0, seed: int = 0):
        if not 0 < min_wavelength <= max_wavelength:
            raise ConfigError(f"texture wavelengths must satisfy 0 < min <= max, got "
                              f"{min_wavelength}, {max_wavelength}")
        if components < 1:
            raise ConfigError(f"texture needs at least one component, got {components}")
        rng = np.random.default_rng(seed)
        dirs = _fibonacci_sphere(components) @ _random_rotation(rng).T
        lam = np.exp(np.linspace(math.log(min_wavelength), math.log(max_wavelength),
                                 components))
        rng.shuffle(lam)
        self.dark = np.asarray(dark_bgr, dtype=np.float32).reshape(3, 1)
        self.light = np.asarray(light_bgr, dtype=np.float32).reshape(3, 1)
        self.min_wavelength = float(min_wavelength)
        self._omega = (dirs * (2 * np.pi / lam)[:, None]).astype(np.float32)  # (K, 3)
        self._phase = rng.uniform(0, 2 * np.pi, (components, 1)).astype(np.float32)
        self._gain = np.full(components, contrast * math.sqrt(2.0 / components), np.float32)

    def albedo(self, points: np.ndarray, anchor: np.ndarray) -> np.ndarray:
        """BGR (3, N) float32 in 0..255 at ``points`` (3, N), base frame.

        ``anchor`` (3,) is a fixed point near the surface; subtracting it keeps float32 phases
        small (the texture stays a function of the world point).
        """
        p = (np.asarray(points, dtype=np.float64) - np.reshape(anchor, (3, 1)))
        arg = np.einsum("kj,jn->kn", self._omega, p.astype(np.float32))  # no BLAS threads
        arg += self._phase
        np.sin(arg, out=arg)
        x = self._gain @ arg
        v = 0.5 + 0.5 * x / np.sqrt(1.0 + x * x)  # smooth sigmoid: contrast without aliasing
        return self.dark + v * (self.light - self.dark)


def _fibonacci_sphere(n: int) -> np.ndarray:
    """``n`` unit vectors (n, 3) spread evenly over the sphere (golden-angle spiral)."""
    k = np.arange(n) + 0.5
    z = 1.0 - 2.0 * k / n
    phi = k * math.pi * (3.0 - math.sqrt(5.0))
    r = np.sqrt(1.0 - z * z)
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)


def _random_rotation(rng: np.random.Generator) -> np.ndarray:
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    q = q * np.sign(np.diag(r))
    return q if np.linalg.det(q) > 0 else -q



class SurfaceTexture(ABC):
    """A texture defined on a primitive's surface coordinates (s, t) in metres
    (:meth:`Primitive.surface_coords`) instead of on 3D points."""

    @abstractmethod
    def sample(self, s: np.ndarray, t: np.ndarray) -> np.ndarray:
        """BGR (3, N) float32 at surface coordinates (s, t) (metres, arrays of N)."""


class PhotoTexture(SurfaceTexture):
    """A photograph on a surface: colour at surface coordinates (s, t) in metres
    (:meth:`Primitive.surface_coords`), the image tiled with ``pixel_size`` metres per pixel,
    bilinear. A grey image is tinted: ``tint_bgr`` (3 factors, 1 = keep grey). ``gain`` and
    ``offset`` adjust its contrast (grey levels)."""

    def __init__(self, image: np.ndarray, pixel_size: float, *,
                 tint_bgr: Sequence[float] = (1.0, 1.0, 1.0), gain: float = 1.0,
                 offset: float = 0.0):
        img = np.asarray(image)
        if img.ndim == 2:
            img = img[..., None].repeat(3, axis=2)
        if img.ndim != 3 or img.shape[2] != 3 or img.shape[0] < 2 or img.shape[1] < 2:
            raise ConfigError(f"a photo texture needs an (H, W) or (H, W, 3) image, got "
                              f"{np.shape(image)}")
        if not pixel_size > 0:
            raise ConfigError(f"photo texture pixel size must be > 0 m, got {pixel_size}")
        tinted = img.astype(np.float32) * np.asarray(tint_bgr, np.float32) * gain + offset
        self.image = np.clip(tinted, 0, 255).astype(np.float32)
        self.pixel_size = float(pixel_size)

    def sample(self, s: np.ndarray, t: np.ndarray) -> np.ndarray:
        """BGR (3, N) float32 at surface coordinates (s, t) (metres, arrays of N)."""
        h, w = self.image.shape[:2]
        u = np.mod(np.asarray(s, np.float64).ravel() / self.pixel_size, w).astype(np.float32)
        v = np.mod(np.asarray(t, np.float64).ravel() / self.pixel_size, h).astype(np.float32)
        n = u.size
        if n == 0:
            return np.zeros((3, 0), np.float32)
        cols = _REMAP_COLS  # cv2.remap maps must stay below 32767 in each dimension
        rows = -(-n // cols)
        mu, mv = np.zeros(rows * cols, np.float32), np.zeros(rows * cols, np.float32)
        mu[:n], mv[:n] = u, v
        out = cv2.remap(self.image, mu.reshape(rows, cols), mv.reshape(rows, cols),
                        cv2.INTER_LINEAR, borderMode=cv2.BORDER_WRAP)
        return out.reshape(-1, 3)[:n].T


_REMAP_COLS = 1024
