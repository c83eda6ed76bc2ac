"""OpenCV StereoSGBM as the matcher's peer, in the conventions of :mod:`.stereo`."""

from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor
from typing import Any

import cv2
import numpy as np

from armstereo.reconstruct.rejection import reject_invalid_partners
from armstereo.reconstruct.stereo_inputs import prepare
from armstereo.reconstruct.stereo_options import SgbmOptions, options_for, with_keywords

_MODES = {"sgbm": cv2.STEREO_SGBM_MODE_SGBM, "hh": cv2.STEREO_SGBM_MODE_HH,
          "3way": cv2.STEREO_SGBM_MODE_SGBM_3WAY, "hh4": cv2.STEREO_SGBM_MODE_HH4}
# px: a shifted match's answer joins the average only this close to the unshifted one (a
# shifted image may tip a pixel to another surface; that answer must not drag the mean)
SHIFT_AGREEMENT = 1.0


def sgbm(left: np.ndarray, right: np.ndarray, max_disparity: int,
         options: SgbmOptions | None = None, *, min_disparity: int = 0,
         left_mask: np.ndarray | None = None, right_mask: np.ndarray | None = None,
         **keywords: Any) -> np.ndarray:
    """OpenCV StereoSGBM as a peer: float32 disparity of the left image, NaN = no match.

    ``options``: :class:`.stereo_options.SgbmOptions` (None: the defaults); its fields may
    also be given as keywords (``block_size=7``), which change those of ``options``.
    ``numDisparities`` is ``max_disparity + 1`` rounded up to a multiple of 16; answers outside
    ``[min_disparity, min_disparity + max_disparity]`` become NaN, as do SGBM's invalid pixels
    (it answers nothing in the left band ``x < min_disparity + numDisparities - 1``) and left
    pixels whose partner lies outside the right image or its mask.
    P1 = 8 cn bs^2, P2 = 32 cn bs^2 (OpenCV's recommended smoothness). ``presmooth`` blurs
    both images first; ``shifts`` > 1 averages the matches of sub-pixel shifted right images
    (:func:`shift_averaged`).
    """
    o = with_keywords(options_for("sgbm", options), keywords, "sgbm")
    left, right, lmask, rmask = prepare(left, right, max_disparity, min_disparity, left_mask,
                                        right_mask)
    cn, bs = left.shape[2], o.block_size
    num = -(-(max_disparity + 1) // 16) * 16
    left, right = _squeeze(left), _squeeze(right)
    if o.presmooth > 0:
        left, right = (cv2.GaussianBlur(img, (0, 0), o.presmooth) for img in (left, right))

    def match(right_image: np.ndarray) -> np.ndarray:
        # one matcher per call: it keeps its work buffers, so threads must not share one
        matcher = cv2.StereoSGBM_create(
            minDisparity=min_disparity, numDisparities=num, blockSize=bs,
            P1=8 * cn * bs ** 2, P2=32 * cn * bs ** 2, disp12MaxDiff=o.lr_tolerance,
            uniquenessRatio=o.uniqueness, speckleWindowSize=o.speckle_window,
            speckleRange=o.speckle_range, mode=_MODES[o.mode])
        raw = matcher.compute(left, right_image)
        disp = raw.astype(np.float32) / 16.0
        disp[raw < min_disparity * 16] = np.nan  # SGBM's "no answer" (and its left band)
        return disp

    disp = shift_averaged(match, right, o.shifts)
    bad = (disp > min_disparity + max_disparity) | ~lmask  # NaN compares False: stays NaN
    disp[bad] = np.nan
    reject_invalid_partners(disp, rmask)
    return disp


def shift_averaged(match, right: np.ndarray, shifts: int) -> np.ndarray:
    """``match(right)`` (float32 disparities of the left image, NaN = none) averaged with
    ``match(right moved left by k / shifts px) - k / shifts`` for ``k = 1 .. shifts - 1``.

    Moving the right image's content left by ``s`` px (``R'(x) = R(x + s)``, bicubic, edge
    replicated) raises every true disparity by ``s``, so the parabola's locking error, which
    is periodic in the disparity's fraction, is met at ``shifts`` evenly spaced phases and its
    first ``shifts - 1`` harmonics cancel in the mean. A shifted answer joins only where it is
    within :data:`SHIFT_AGREEMENT` px of the unshifted one; pixels the unshifted match does
    not answer stay NaN, so the density is the unshifted match's.
    """
    if shifts <= 1:
        return match(right)
    h, w = right.shape[:2]

    def shifted_match(k: int) -> np.ndarray:
        if k == 0:
            return match(right)
        s = k / shifts
        moved = cv2.warpAffine(right, np.float32([[1, 0, s], [0, 1, 0]]), (w, h),
                               flags=cv2.INTER_CUBIC | cv2.WARP_INVERSE_MAP,
                               borderMode=cv2.BORDER_REPLICATE)
        return match(moved) - np.float32(s)

    # OpenCV's 5- and 8-path modes run on one core and release the GIL: the matches of the
    # shifted images run side by side (the map does not depend on the thread count)
    with ThreadPoolExecutor(max_workers=min(shifts, os.cpu_count() or 1)) as pool:
        base, *others = pool.map(shifted_match, range(shifts))
    total = np.where(np.isfinite(base), base, 0.0).astype(np.float32)
    count = np.isfinite(base).astype(np.float32)
    for d in others:
        agree = np.abs(d - base) <= SHIFT_AGREEMENT  # False wherever either is NaN
        total += np.where(agree, d, 0.0)
        count += agree
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(count > 0, total / count, np.nan).astype(np.float32)


def _squeeze(img: np.ndarray) -> np.ndarray:
    return img[:, :, 0] if img.shape[2] == 1 else img
