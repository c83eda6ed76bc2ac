"""What a real sensor and lens do to the mock camera's clean renders (the ``image`` group of a
mock profile, :class:`drivers.mock.profile.ImageEffects`).

Applied in the order light takes: vignetting (the lens), the view's exposure and white balance
(the camera's automatic gain settles slightly differently for every shot), defocus blur, then
photon (shot) and read noise, then 8-bit quantisation. All random draws come from the
generator passed in, so a capture is reproducible.
"""

from __future__ import annotations

import functools

import cv2
import numpy as np

from armstereo.photometric.vignetting import Vignetting
from drivers.mock.profile import ImageEffects


def view_gains(effects: ImageEffects, rng: np.random.Generator) -> np.ndarray:
    """Per-channel gain (3,) of one view: overall exposure times each channel's white balance
    (drawn always, so switching one effect off keeps the other's draws)."""
    unit = rng.standard_normal(4)
    return (1.0 + effects.exposure_rel * unit[0]) * (1.0 + effects.white_balance_rel * unit[1:])


@functools.lru_cache(maxsize=4)
def vignetting_map(height: int, width: int, strength: float) -> np.ndarray:
    """Relative brightness (H, W) float32: 1 at the image centre, ``1 - strength`` at the
    corners, falling with the squared distance from the centre (the cos^4 law's first term).
    For a lens without a fall-off of its own (:func:`drivers.mock.cell.true_vignetting`)."""
    v, u = np.mgrid[0:height, 0:width].astype(np.float32)
    r2 = ((u - (width - 1) / 2) ** 2 + (v - (height - 1) / 2) ** 2)
    return (1.0 - strength * r2 / r2.max()).astype(np.float32)


def apply_effects(image: np.ndarray, effects: ImageEffects, rng: np.random.Generator,
                  gains: np.ndarray | None = None,
                  vignetting: Vignetting | None = None) -> np.ndarray:
    """``image`` (H, W, 3) uint8 BGR as the sensor delivers it; ``gains`` (3,) the view's
    exposure and white balance (default: drawn from ``rng``); ``vignetting`` the lens's own
    fall-off (default: the centred quadratic of ``effects.vignetting``)."""
    if not effects.any:
        return image
    img = image.astype(np.float32)
    h, w = img.shape[:2]
    if effects.vignetting > 0:
        fall_off = (vignetting.gain_map() if vignetting is not None
                    else vignetting_map(h, w, float(effects.vignetting)))
        img *= fall_off[..., None]
    gains = view_gains(effects, rng) if gains is None else np.asarray(gains, dtype=np.float32)
    img *= gains.astype(np.float32)
    if effects.blur_sigma_px > 0:
        img = cv2.GaussianBlur(img, (0, 0), float(effects.blur_sigma_px))
    noise = rng.standard_normal(img.shape).astype(np.float32)
    variance = effects.read_noise ** 2 + effects.shot_noise_gain * np.clip(img, 0, None)
    img += noise * np.sqrt(variance)
    return np.clip(np.rint(img), 0, 255).astype(np.uint8)
