"""OpenCV StereoSGBM as the matcher's peer, in the conventions of :mod:`.stereo`."""

from __future__ import annotations

from typing import Any

import cv2
import numpy as np

from armstereo.reconstruct.rejection import reject_invalid_partners
from armstereo.reconstruct.stereo_inputs import prepare
from armstereo.reconstruct.stereo_options import SgbmOptions, options_for, with_keywords


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
    P1 = 8 cn bs^2, P2 = 32 cn bs^2 (OpenCV's recommended smoothness).
    """
    o = with_keywords(options_for("sgbm", options), keywords, "sgbm")
    left, right, lmask, rmask = prepare(left, right, max_disparity, min_disparity, left_mask,
                                        right_mask)
    cn, bs = left.shape[2], o.block_size
    num = -(-(max_disparity + 1) // 16) * 16
    matcher = cv2.StereoSGBM_create(
        minDisparity=min_disparity, numDisparities=num, blockSize=bs,
        P1=8 * cn * bs ** 2, P2=32 * cn * bs ** 2, disp12MaxDiff=o.lr_tolerance,
        uniquenessRatio=o.uniqueness, speckleWindowSize=o.speckle_window,
        speckleRange=o.speckle_range, mode=cv2.STEREO_SGBM_MODE_SGBM)
    raw = matcher.compute(_squeeze(left), _squeeze(right))
    disp = raw.astype(np.float32) / 16.0
    bad = (raw < min_disparity * 16) | (disp > min_disparity + max_disparity) | ~lmask
    disp[bad] = np.nan
    reject_invalid_partners(disp, rmask)
    return disp


def _squeeze(img: np.ndarray) -> np.ndarray:
    return img[:, :, 0] if img.shape[2] == 1 else img
