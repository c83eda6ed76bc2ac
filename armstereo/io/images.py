"""Images for people: colorized disparity, 16-bit depth PNG, rectified pair, depth error.

Every function returns a BGR uint8 image (or uint16 for depth); ``write_png`` stores one
atomically. Colour bars carry their range in text so a picture explains itself.
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from armstereo.errors import StereoError
from armstereo.io.files import write_bytes_atomic

DEPTH_PNG_SCALE = 1000.0  # depth PNG units per metre: millimetres
LEGEND_HEIGHT = 28
NONE_BGR = (0, 0, 0)  # unknown disparity
NO_TRUTH_BGR = (128, 128, 128)  # unknown depth error
EPIPOLAR_COLORS = [(0, 0, 255), (0, 255, 0), (255, 0, 0), (0, 255, 255), (255, 0, 255),
                   (255, 255, 0), (0, 128, 255), (255, 128, 0)]


def _finite_range(values: np.ndarray, lo: float | None, hi: float | None) -> tuple[float, float]:
    finite = values[np.isfinite(values)]
    if lo is None:
        lo = float(finite.min()) if finite.size else 0.0
    if hi is None:
        hi = float(finite.max()) if finite.size else 1.0
    return lo, (hi if hi > lo else lo + 1.0)


def _colormap(values: np.ndarray, lo: float, hi: float, colormap: int) -> np.ndarray:
    with np.errstate(invalid="ignore"):
        scaled = np.clip((values - lo) / (hi - lo), 0.0, 1.0)
    return cv2.applyColorMap(np.nan_to_num(scaled * 255.0).astype(np.uint8), colormap)


def _legend(width: int, lo: float, hi: float, unit: str, colormap: int) -> np.ndarray:
    """A colour bar from lo to hi with both ends and the unit written on it."""
    bar = np.linspace(0, 255, max(width, 2)).astype(np.uint8)[None, :].repeat(LEGEND_HEIGHT, 0)
    bar = cv2.applyColorMap(bar, colormap)
    font, scale = cv2.FONT_HERSHEY_SIMPLEX, 0.45
    for text, x in ((f"{lo:.3g} {unit}", 4), (f"{hi:.3g} {unit}", None)):
        (tw, th), _ = cv2.getTextSize(text, font, scale, 1)
        x = width - tw - 4 if x is None else x
        org = (x, (LEGEND_HEIGHT + th) // 2)
        cv2.putText(bar, text, org, font, scale, (0, 0, 0), 3, cv2.LINE_AA)
        cv2.putText(bar, text, org, font, scale, (255, 255, 255), 1, cv2.LINE_AA)
    return bar


def colorize_disparity(disparity: np.ndarray, d_min: float | None = None,
                       d_max: float | None = None, *, legend: bool = True) -> np.ndarray:
    """Disparity (pixels, NaN = none) as a TURBO-coloured BGR image: near is red, far blue,
    unmatched black. The range defaults to the finite values' min..max; a legend bar underneath
    states it."""
    disparity = np.asarray(disparity, dtype=np.float32)
    lo, hi = _finite_range(disparity, d_min, d_max)
    img = _colormap(disparity, lo, hi, cv2.COLORMAP_TURBO)
    img[~np.isfinite(disparity)] = NONE_BGR
    if legend:
        img = np.vstack([img, _legend(img.shape[1], lo, hi, "px", cv2.COLORMAP_TURBO)])
    return img


def depth_to_png16(depth: np.ndarray) -> np.ndarray:
    """Depth in metres (float, NaN = none) -> uint16 millimetres, 0 = none, clipped at 65.535 m."""
    depth = np.asarray(depth, dtype=np.float64)
    with np.errstate(invalid="ignore"):
        mm = np.where(np.isfinite(depth) & (depth > 0), np.round(depth * DEPTH_PNG_SCALE), 0)
    return np.clip(mm, 0, np.iinfo(np.uint16).max).astype(np.uint16)


def depth_from_png16(depth_mm: np.ndarray) -> np.ndarray:
    """uint16 millimetres (0 = none) -> float32 metres with NaN = none."""
    depth_mm = np.asarray(depth_mm)
    return np.where(depth_mm > 0, depth_mm / DEPTH_PNG_SCALE, np.nan).astype(np.float32)


def side_by_side(left: np.ndarray, right: np.ndarray, *, lines: int = 8) -> np.ndarray:
    """Rectified left|right next to each other with ``lines`` horizontal epipolar lines: a
    feature should sit on the same line in both halves."""
    if left.shape[:2] != right.shape[:2]:
        raise StereoError(f"rectified images differ in size: {left.shape[:2]} vs "
                          f"{right.shape[:2]}")
    img = np.hstack([_bgr(left), _bgr(right)])
    h = img.shape[0]
    for i in range(lines):
        y = int(round((i + 0.5) * h / lines))
        cv2.line(img, (0, y), (img.shape[1] - 1, y), EPIPOLAR_COLORS[i % len(EPIPOLAR_COLORS)], 1)
    cv2.line(img, (left.shape[1], 0), (left.shape[1], h - 1), (255, 255, 255), 1)
    return img


def _bgr(image: np.ndarray) -> np.ndarray:
    return cv2.cvtColor(image, cv2.COLOR_GRAY2BGR) if image.ndim == 2 else image.copy()


def depth_error_map(depth: np.ndarray, truth: np.ndarray, *, max_relative: float = 0.05,
                    legend: bool = True) -> np.ndarray:
    """|depth - truth| / truth as a colour image (0 blue .. ``max_relative`` and above red);
    grey where either value is missing. Both maps in metres, same size."""
    depth = np.asarray(depth, dtype=np.float64)
    truth = np.asarray(truth, dtype=np.float64)
    if depth.shape != truth.shape:
        raise StereoError(f"depth {depth.shape} and ground truth {truth.shape} differ in size")
    with np.errstate(invalid="ignore", divide="ignore"):
        rel = np.abs(depth - truth) / truth
    known = np.isfinite(rel) & (truth > 0)
    img = _colormap(np.where(known, rel, np.nan), 0.0, max_relative, cv2.COLORMAP_JET)
    img[~known] = NO_TRUTH_BGR
    if legend:
        bar = _legend(img.shape[1], 0.0, 100.0 * max_relative, "%", cv2.COLORMAP_JET)
        img = np.vstack([img, bar])
    return img


def write_png(path: str | Path, image: np.ndarray) -> Path:
    """Encode ``image`` (uint8 grey/BGR or uint16 grey) as PNG and write it atomically."""
    ok, buf = cv2.imencode(".png", image)
    if not ok:
        raise StereoError(f"could not encode a {image.dtype} {image.shape} image as PNG")
    return write_bytes_atomic(path, buf.tobytes())


def write_depth_png(path: str | Path, depth: np.ndarray) -> Path:
    """Write depth (m) as a 16-bit PNG in millimetres (0 = none)."""
    return write_png(path, depth_to_png16(depth))
