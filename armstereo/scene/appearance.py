"""Colour statistics and a texture measure of an object, from its coloured points.

Colour (RGB, 0..255): mean and standard deviation per channel, plus the circular mean hue
(degrees, weighted by saturation, so grey points do not vote), mean saturation and value
(0..1). Texture is measured on a top view of the object: the grey level (mean per cell of
``cell_m``, 1 mm by default) over the object's footprint, and

- ``grey_std``: spread of the grey level (0..255): contrast of the pattern;
- ``gradient_per_mm``: mean absolute grey difference between neighbouring cells per mm:
  how busy the pattern is (fine-grained materials score high, smooth paint low);
- ``entropy_bits``: Shannon entropy of a 32-bin grey histogram (0..5 bits).

These are what a material classifier (e.g. soil vs rock) would be fed; no classifier here.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

TEXTURE_CELL_M = 0.001
ENTROPY_BINS = 32
_M_PER_MM = 0.001


@dataclass(frozen=True)
class Appearance:
    """Colour and texture of one object (see module doc for units)."""

    mean_rgb: tuple[float, float, float]
    std_rgb: tuple[float, float, float]
    hue_deg: float | None  # None when the object is grey (no saturated point)
    saturation: float
    value: float
    grey_std: float
    gradient_per_mm: float
    entropy_bits: float

    def as_dict(self) -> dict:
        r = _round
        return {"color": {"mean_rgb": [r(v, 1) for v in self.mean_rgb],
                          "std_rgb": [r(v, 1) for v in self.std_rgb],
                          "hue_deg": None if self.hue_deg is None else r(self.hue_deg, 1),
                          "saturation": r(self.saturation, 3), "value": r(self.value, 3)},
                "texture": {"grey_std": r(self.grey_std, 2),
                            "gradient_per_mm": r(self.gradient_per_mm, 2),
                            "entropy_bits": r(self.entropy_bits, 3),
                            "cell_mm": r(TEXTURE_CELL_M * 1000, 2)}}


def _round(v: float, nd: int) -> float:
    return round(float(v), nd)


def appearance(uv: np.ndarray, colors_bgr: np.ndarray, *,
               cell_m: float = TEXTURE_CELL_M) -> Appearance:
    """Colour and texture of points with plane coordinates ``uv`` (N, 2, m) and colours
    ``colors_bgr`` (N, 3) uint8."""
    bgr = np.asarray(colors_bgr, dtype=np.uint8).reshape(-1, 3)
    rgb = bgr[:, ::-1].astype(float)
    hsv = cv2.cvtColor(bgr.reshape(-1, 1, 3), cv2.COLOR_BGR2HSV_FULL).reshape(-1, 3)
    hue = hsv[:, 0].astype(float) * (2 * np.pi / 256.0)
    sat = hsv[:, 1].astype(float) / 255.0
    weight = sat.sum()
    hue_deg = None
    if weight > 0:
        ang = np.arctan2((sat * np.sin(hue)).sum(), (sat * np.cos(hue)).sum())
        hue_deg = float(np.degrees(ang) % 360.0)
    grey = cv2.cvtColor(bgr.reshape(-1, 1, 3), cv2.COLOR_BGR2GRAY).reshape(-1).astype(float)
    g_std, g_grad, g_ent = _texture(np.asarray(uv, dtype=float), grey, cell_m)
    return Appearance(tuple(rgb.mean(axis=0)), tuple(rgb.std(axis=0)), hue_deg,
                      float(sat.mean()), float(hsv[:, 2].mean() / 255.0), g_std, g_grad, g_ent)


def _texture(uv: np.ndarray, grey: np.ndarray, cell_m: float) -> tuple[float, float, float]:
    """(grey_std, gradient_per_mm, entropy_bits) of the top-view grey raster."""
    ij = np.floor((uv - uv.min(axis=0)) / cell_m).astype(np.int64)
    shape = (int(ij[:, 1].max()) + 1, int(ij[:, 0].max()) + 1)
    flat = ij[:, 1] * shape[1] + ij[:, 0]
    total = np.bincount(flat, weights=grey, minlength=shape[0] * shape[1]).reshape(shape)
    count = np.bincount(flat, minlength=shape[0] * shape[1]).reshape(shape)
    known = count > 0
    img = np.where(known, total / np.maximum(count, 1.0), np.nan)
    vals = img[known]
    diffs = [np.abs(np.diff(img, axis=a)) for a in (0, 1)]
    d = np.concatenate([x[np.isfinite(x)] for x in diffs])
    gradient = float(d.mean() / (cell_m / _M_PER_MM)) if d.size else 0.0
    hist, _ = np.histogram(vals, bins=ENTROPY_BINS, range=(0.0, 256.0))
    p = hist[hist > 0] / hist.sum()
    return float(vals.std()), gradient, float(-(p * np.log2(p)).sum())
