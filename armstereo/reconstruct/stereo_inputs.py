"""What the matchers start from: checked inputs, grey images, prefilters and texture maps.

:func:`prepare` checks a pair and its validity masks for both matchers (images uint8, grey
(H, W) or BGR (H, W, 3), the disparity window inside the image). :func:`match_inputs` makes,
on strips of rows side by side (:mod:`.strips`), the grey images, the images the programme
matches (:func:`with_edges`, the default prefilter) and the left image's texture maps
(:func:`texture_strength`: which pixels are flat, which earn the match reward), after the
local normalisation (:mod:`.normalize`) when it is on. :func:`highpass` is the other prefilter,
on whole images.
"""

from __future__ import annotations

from typing import NamedTuple

import cv2
import numpy as np

from armstereo.errors import StereoError
from armstereo.reconstruct.normalize import normalize
from armstereo.reconstruct.strips import each_strip

TEXTURE_WINDOW = 5  # pixels: side of the texture map's box filter
INPUT_HALO = 1 + TEXTURE_WINDOW // 2  # rows the texture map's Sobel and box filter reach


def prepare(left, right, max_disparity, min_disparity, left_mask, right_mask
            ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Validate a pair; returns (H, W, C) uint8 images and (H, W) bool masks (all True where
    no mask is given). StereoError names what is wrong."""
    images = [_checked_image(name, img) for name, img in (("left", left), ("right", right))]
    left, right = images
    if left.shape != right.shape:
        raise StereoError(f"image sizes differ: left {left.shape[1]}x{left.shape[0]}x"
                          f"{left.shape[2]}, right {right.shape[1]}x{right.shape[0]}x"
                          f"{right.shape[2]}")
    H, W = left.shape[:2]
    check_range(max_disparity, min_disparity, W)
    masks = []
    for name, mask in (("left_mask", left_mask), ("right_mask", right_mask)):
        if mask is None:
            masks.append(np.ones((H, W), np.bool_))
            continue
        mask = np.asarray(mask)
        if mask.shape != (H, W):
            raise StereoError(f"{name} has shape {mask.shape}, expected the image's {(H, W)}")
        masks.append(np.ascontiguousarray(mask.astype(np.bool_)))
    return left, right, masks[0], masks[1]


def _checked_image(name: str, img) -> np.ndarray:
    if not isinstance(img, np.ndarray):
        raise StereoError(f"{name} image must be a numpy array, got {type(img).__name__}")
    if img.size == 0:
        raise StereoError(f"{name} image is empty (shape {img.shape})")
    if img.dtype != np.uint8:
        raise StereoError(f"{name} image must be uint8, got {img.dtype}")
    if img.ndim == 2:
        img = img[:, :, None]
    if img.ndim != 3 or img.shape[2] not in (1, 3):
        raise StereoError(f"{name} image must be (H, W) grey or (H, W, 3) BGR, "
                          f"got shape {img.shape}")
    return np.ascontiguousarray(img)


def check_range(max_disparity, min_disparity, width: int) -> None:
    """The searched disparities ``min_disparity .. min_disparity + max_disparity`` (whole
    numbers, max >= 1, min >= 0) must lie inside an image ``width`` wide."""
    for name, value in (("max_disparity", max_disparity), ("min_disparity", min_disparity)):
        if isinstance(value, bool) or not isinstance(value, int | np.integer):
            raise StereoError(f"{name} must be an integer, got {value!r}")
    if max_disparity <= 0:
        raise StereoError(f"max_disparity must be >= 1, got {max_disparity}")
    if min_disparity < 0:
        raise StereoError(f"min_disparity must be >= 0, got {min_disparity}")
    if min_disparity + max_disparity >= width:
        raise StereoError(f"min_disparity + max_disparity = {min_disparity + max_disparity} "
                          f"must be < the image width {width}")


def grey(img: np.ndarray) -> np.ndarray:
    """(H, W) uint8 grey image of an (H, W, C) image (OpenCV BGR2GRAY weights)."""
    if img.shape[2] == 1:
        return np.ascontiguousarray(img[:, :, 0])
    return cv2.cvtColor(img, cv2.COLOR_BGR2GRAY)


class MatchInputs(NamedTuple):
    """What :func:`match_inputs` makes, each a (H, W) array: ``grey`` the (left, right) grey
    images; ``base`` what the programme's prefilter and the sub-pixel steps start from (the
    locally normalised grey images, :mod:`.normalize`, or the grey ones when that is off);
    ``matched`` the images the programme matches (``base`` with edges, :func:`with_edges`,
    or ``base`` itself); ``flat``/``textured`` the left image's texture maps (None if off)."""

    grey: tuple[np.ndarray, np.ndarray]
    base: tuple[np.ndarray, np.ndarray]
    matched: tuple[np.ndarray, np.ndarray]
    flat: np.ndarray | None
    textured: np.ndarray | None


def match_inputs(pool, strips: list[tuple[int, int]], left: np.ndarray, right: np.ndarray,
                 masks: tuple[np.ndarray, np.ndarray], *, edge_cap: float | None,
                 normalized: tuple[int, float, float] | None, flat_below: float,
                 reward_from: float) -> MatchInputs:
    """What the programme and the checks start from (:class:`MatchInputs`), on ``strips`` of
    rows side by side: ``normalized`` = ``(window, floor, scale)`` of the local normalisation
    (:func:`.normalize.normalize`, over the valid pixels of ``masks``; None = off), the edge
    images when ``edge_cap`` is given, the left image's flat pixels (texture strength of the
    grey image below ``flat_below``; None if 0) and those that earn the match reward
    (strength at least ``reward_from``, :func:`rewarded`; None if 0)."""
    H, W = left.shape[:2]
    grey2 = np.empty((2, H, W), np.uint8)
    base = grey2 if normalized is None else np.empty((2, H, W), np.uint8)
    matched = base if edge_cap is None else np.empty((2, H, W), np.uint8)
    flat = np.empty((H, W), np.bool_) if flat_below > 0 else None
    textured = np.empty((H, W), np.bool_) if reward_from > 0 else None
    halo = INPUT_HALO if normalized is None else max(INPUT_HALO, normalized[0] // 2 + 1)
    each_strip(pool, strips, _input_rows, left, right, masks, halo, edge_cap, normalized,
               flat_below, reward_from, grey2, base, matched, flat, textured)
    return MatchInputs((grey2[0], grey2[1]), (base[0], base[1]), (matched[0], matched[1]),
                       flat, textured)


def _input_rows(first: int, stop: int, left: np.ndarray, right: np.ndarray, masks, halo: int,
                edge_cap: float | None, normalized: tuple[int, float, float] | None,
                flat_below: float, reward_from: float, grey2: np.ndarray, base: np.ndarray,
                matched: np.ndarray, flat: np.ndarray | None,
                textured: np.ndarray | None) -> None:
    """Rows ``first .. stop - 1`` of :func:`match_inputs`, filtered from ``halo`` rows more on
    each side (the filters' own border only touches rows that are dropped)."""
    a, b = max(0, first - halo), min(left.shape[0], stop + halo)
    rows, keep = slice(first, stop), slice(first - a, stop - a)
    for i, img in enumerate((left, right)):
        g = grey(img[a:b])
        grey2[i, rows] = g[keep]
        if i == 0 and (flat is not None or textured is not None):
            # one texture map of the left image serves both thresholds; it reads the grey
            # image, whose contrast says how much the programme's answer there is worth (the
            # normalised image has about the same contrast everywhere)
            strength = texture_strength(g)[keep]
            if flat is not None:
                np.less(strength, flat_below, out=flat[rows])
            if textured is not None:
                textured[rows] = rewarded(strength, reward_from)  # the rule in one place
        if normalized is not None:
            g = normalize(g, masks[i][a:b], *normalized)
            base[i, rows] = g[keep]
        if edge_cap is not None:
            matched[i, rows] = with_edges(g, edge_cap)[keep]


def texture_strength(grey_image: np.ndarray) -> np.ndarray:
    """Mean absolute horizontal gradient over the TEXTURE_WINDOW square, grey levels per
    pixel (Sobel / 8 = central difference, smoothed): below a threshold a pixel is flat."""
    # scale 1/8 inside the filter: exact, as every Sobel sum is an integer
    gx = cv2.Sobel(grey_image, cv2.CV_32F, 1, 0, ksize=3, scale=1 / 8)
    np.abs(gx, out=gx)
    return cv2.blur(gx, (TEXTURE_WINDOW, TEXTURE_WINDOW), dst=gx)


def rewarded(strength: np.ndarray | None, threshold: float) -> np.ndarray | None:
    """Pixels whose match earns the reward: those with texture (None = all), from
    :func:`texture_strength`."""
    if threshold <= 0:
        return None
    return ~(strength < threshold)


def highpass(grey_image: np.ndarray, mask: np.ndarray, sigma: float, gain: float) -> np.ndarray:
    """``gain * (I - local mean) + 128`` as uint8; the local mean is a Gaussian average over
    the valid pixels only, so a rectification's black fill does not darken the border.
    ``sigma`` (px) and ``gain`` > 0, as :class:`.stereo_options.BirchfieldOptions` checks."""
    g = grey_image.astype(np.float32)
    w = mask.astype(np.float32)
    num = cv2.GaussianBlur(g * w, (0, 0), sigma)
    den = cv2.GaussianBlur(w, (0, 0), sigma)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = np.where(den > 1e-3, num / den, g)
    out = np.float32(gain) * (g - mean) + np.float32(128)
    return np.clip(np.rint(out), 0, 255).astype(np.uint8)


def with_edges(grey_image: np.ndarray, cap: float) -> np.ndarray:
    """``I + clip(Sobel_x(I), -cap, cap)`` as uint8 (saturated): the matched image of
    ``prefilter="edges"``; ``cap`` > 0 grey levels, as :class:`.stereo_options.BirchfieldOptions`
    checks."""
    sx = cv2.Sobel(grey_image, cv2.CV_16S, 1, 0, ksize=3)
    c = int(round(cap))
    np.clip(sx, -c, c, out=sx)
    return cv2.add(grey_image, sx, dtype=cv2.CV_8U)
