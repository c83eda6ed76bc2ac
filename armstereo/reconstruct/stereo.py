"""Dense disparity for a rectified pair: Birchfield-Tomasi (the paper's matcher) or OpenCV SGBM.

Conventions (shared by both methods): images are uint8, grey (H, W) or BGR (H, W, 3), already
rectified so that a left pixel ``(x, y)`` with disparity ``d`` matches the right pixel
``(x - d, y)``. The result is float32 disparity of the *left* image, NaN where there is no
match (occluded, outside the other view or the search window, masked out, or rejected by a
consistency check). The searched disparities are ``min_disparity .. min_disparity +
max_disparity`` inclusive.

Validity masks (``left_mask``/``right_mask``, True = real pixel) mark the pixels a
rectification warp filled in from outside the source image: they take no part in matching
(their black fill would create false edges) and get NaN.

The front door is :func:`disparity`: an options object
(:class:`~.stereo_options.BirchfieldOptions` or :class:`~.stereo_options.SgbmOptions`,
validated when made) says which matcher runs and how. :func:`birchfield` and :func:`.sgbm.sgbm`
are the matchers themselves, which also take their options as keywords (``birchfield(left,
right, n, **PAPER_OPTIONS)``); :func:`compute_disparity` is the older keyword form of
:func:`disparity`. The defaults were chosen by measurement, on data held out of the tuning
too: docs/birchfield-tomasi.md ("Defaults and why") says what each changes and why.

:func:`birchfield`'s stages, each in a module of its own:

1. inputs (:mod:`.stereo_inputs`): checks, grey images, the prefilter, texture maps;
2. matching (:func:`_match`): one dynamic programme per scanline, by
   :mod:`.birchfield` (its package doc names the kernels each option runs);
3. rejection and refinement (:mod:`.rejection`, :mod:`.subpixel`): sub-pixel step, median,
   flat and hidden pixels, the left-right and photo-consistency checks, then the consensus
   median (:mod:`.consensus`), the speckle filter (:mod:`.speckles`) and the partners'
   validity.
"""

from __future__ import annotations

import logging
from typing import Any

import numba
import numpy as np

from armstereo.errors import StereoError
from armstereo.reconstruct.birchfield.columns.vertical import match_image_vertical
from armstereo.reconstruct.birchfield.common.states import BORDER
from armstereo.reconstruct.birchfield.paper import postprocess as paper_steps
from armstereo.reconstruct.birchfield.paper.dp_exact import max_exact_width
from armstereo.reconstruct.birchfield.paper.matcher import DP_EXACT, DP_PRUNED, match_image
from armstereo.reconstruct.birchfield.refine import left_right_mismatch
from armstereo.reconstruct.birchfield.window.aggregate import match_image_aggregated
from armstereo.reconstruct.consensus import replace_outliers
from armstereo.reconstruct.equalize import equalize
from armstereo.reconstruct.normalize import normalize
from armstereo.reconstruct.rejection import (
    add_rejections,
    clip_to_window,
    masked_map,
    photo_inconsistent,
    reject_invalid_partners,
)
from armstereo.reconstruct.saturation import saturation_codes
from armstereo.reconstruct.sgbm import sgbm
from armstereo.reconstruct.speckles import remove_speckles
from armstereo.reconstruct.stereo_inputs import (
    grey,
    highpass,
    match_inputs,
    prepare,
    rewarded,
    texture_strength,
    with_edges,
)
from armstereo.reconstruct.stereo_options import (
    CLEAN_PHOTO_CHECK,
    COLOR_MODES,
    CONSENSUS_SIZE,
    COST_WINDOW,
    EDGE_CAP,
    MATCH_REWARD,
    METHODS,
    OCCLUSION_MARGIN,
    OCCLUSION_MODES,
    PAPER_OPTIONS,
    POSTPROCESS_MODES,
    PREFILTER,
    PREFILTER_MODES,
    REWARD_TEXTURE,
    SEARCH_MODES,
    SLANT_PENALTY,
    SPECKLE_RANGE,
    SPECKLE_SIZE,
    SUBPIXEL_MODES,
    TEXTURE_THRESHOLD,
    BirchfieldOptions,
    SgbmOptions,
    StereoOptions,
    options_for,
    with_keywords,
)
from armstereo.reconstruct.strips import row_strips, thread_pool
from armstereo.reconstruct.subpixel import refine

__all__ = [
    "CLEAN_PHOTO_CHECK", "COLOR_MODES", "CONSENSUS_SIZE", "COST_WINDOW", "EDGE_CAP",
    "MATCH_REWARD", "METHODS", "OCCLUSION_MARGIN", "OCCLUSION_MODES", "PAPER_OPTIONS",
    "POSTPROCESS_MODES", "PREFILTER", "PREFILTER_MODES", "REWARD_TEXTURE", "SEARCH_MODES",
    "SLANT_PENALTY", "SMOOTHING_SCALE", "SPECKLE_RANGE", "SPECKLE_SIZE", "SUBPIXEL_MODES",
    "TEXTURE_THRESHOLD", "BirchfieldOptions", "SgbmOptions", "StereoOptions", "birchfield",
    "compute_disparity", "disparity", "sgbm",
]

log = logging.getLogger(__name__)

# the first pass of the brightness equalisation: the programme on a cost that ignores
# brightness (the locally normalised images), without the texture rules
EQUALIZE_FIRST_PASS = BirchfieldOptions(equalize=False, normalize_window=7,
                                        texture_threshold=0.0, reward_texture=0.0)

# column_smoothing: the smoothed costs weigh as much as this many single-pixel costs when
# the penalties are scaled (2 and 4 measured: bench/results/stereo_consistency.md)
SMOOTHING_SCALE = 3


def disparity(left: np.ndarray, right: np.ndarray, max_disparity: int,
              options: StereoOptions | None = None, *, min_disparity: int = 0,
              left_mask: np.ndarray | None = None,
              right_mask: np.ndarray | None = None) -> np.ndarray:
    """Disparity of the left image by the matcher ``options`` names: Birchfield-Tomasi for
    :class:`BirchfieldOptions` (None: its defaults), OpenCV SGBM for :class:`SgbmOptions`.

    Same conventions and search window for both (see the module doc). Raises StereoError for
    unusable input.
    """
    o = options_for(None, options)
    match = birchfield if o.method == "birchfield" else sgbm
    return match(left, right, max_disparity, o, min_disparity=min_disparity,
                 left_mask=left_mask, right_mask=right_mask)


def compute_disparity(left: np.ndarray, right: np.ndarray, max_disparity: int, *,
                      method: str | None = None, min_disparity: int = 0,
                      left_mask: np.ndarray | None = None, right_mask: np.ndarray | None = None,
                      options: StereoOptions | None = None, **keywords: Any) -> np.ndarray:
    """Disparity of the left image by ``method`` (``"birchfield"`` or ``"sgbm"``; None: the
    one ``options`` names, else ``"birchfield"``): :func:`disparity` with the matcher's
    options as an object, as keywords (which change those of ``options``), or both.
    """
    o = options_for(method, options)
    o = with_keywords(o, keywords, o.method)
    return disparity(left, right, max_disparity, o, min_disparity=min_disparity,
                     left_mask=left_mask, right_mask=right_mask)


def birchfield(left: np.ndarray, right: np.ndarray, max_disparity: int,
               options: BirchfieldOptions | None = None, *, min_disparity: int = 0,
               left_mask: np.ndarray | None = None, right_mask: np.ndarray | None = None,
               **keywords: Any) -> np.ndarray:
    """Birchfield-Tomasi pixel-to-pixel stereo (ICCV'98), made robust for real photographs.

    ``options``: :class:`BirchfieldOptions` (None: the defaults; what each option does is
    documented there); its fields may also be given as keywords (``lr_check=True``,
    ``**PAPER_OPTIONS``), which change those of ``options``. Every returned disparity lies in
    ``[min_disparity, min_disparity + max_disparity]``. Left pixels whose partner ``x - d``
    (nearest pixel) would lie outside the right image (the strip ``x < d``) or on a masked
    right pixel are NaN.

    Raises StereoError for unusable input (sizes, dtype, disparity range, masks, options).
    """
    o = with_keywords(options_for("birchfield", options), keywords, "birchfield")
    left, right, lmask, rmask = prepare(left, right, max_disparity, min_disparity, left_mask,
                                        right_mask)
    n_threads = o.threads or numba.get_num_threads()
    params = _kernel_params(o, left, min_disparity, max_disparity, n_threads)
    # every step but the matching (which has its own threads) runs on strips of rows side by
    # side where it can (the speckle filter on strips of its own)
    strips = row_strips(left.shape[0], n_threads)
    with thread_pool(n_threads) as pool:
        # the photo-consistency check reads the grey images, the sub-pixel steps the
        # normalised ones (the views' brightness may differ) without the edges
        gray = o.color == "gray"
        if gray:  # once: the saturation codes, the equalisation and the inputs all read it
            left, right = grey(left)[:, :, None], grey(right)[:, :, None]
        saturated = _saturated(left, right, o)  # what the recorded levels were, before
        if o.equalize and gray:
            left, right = _equalized(left, right, lmask, rmask, o, min_disparity,
                                     max_disparity, pool)
        inputs = match_inputs(
            pool, strips, left, right, (lmask, rmask),
            edge_cap=o.edge_cap if o.prefilter == "edges" and gray else None,
            normalized=o.normalization, flat_below=o.texture_threshold,
            reward_from=o.reward_texture)
        (grey_l, grey_r), (gl, gr), textured_l = inputs.grey, inputs.matched, inputs.textured
        if o.prefilter == "highpass":
            gl = highpass(inputs.base[0], lmask, o.prefilter_sigma, o.prefilter_gain)
            gr = highpass(inputs.base[1], rmask, o.prefilter_sigma, o.prefilter_gain)
        # the sub-pixel steps fit intensities: the edge image's clipping and saturation are not
        # a shifted copy of the other view's, and its Sobel sees the image border
        sub = inputs.base if o.prefilter == "edges" else (gl, gr)
        matched = ((gl[:, :, None], gr[:, :, None]) if o.color == "gray" else (left, right))
        idx, _ = _match(*matched, lmask, rmask, textured=textured_l, pool=pool,
                        saturated=saturated, **params)
        masked, reject = masked_map(
            pool, strips, *sub, idx, min_disparity, fast=o.subpixel == "fast",
            median=o.postprocess == "median", flat=inputs.flat, columns=o.column_support,
            hidden=o.occlusion_margin if o.occlusions == "nan" else None, plain=o.plain_fill)
        if o.lr_check:
            _reject_right_to_left(masked, reject, idx, matched, (lmask, rmask), grey_r, o,
                                  min_disparity, pool, params, saturated)
        disp = masked
        disp += np.float32(min_disparity)
        disp = _finish(disp, (grey_l, grey_r), sub, rmask, o, min_disparity, max_disparity,
                       pool, strips)
    return disp


def _equalized(left, right, lmask, rmask, o: BirchfieldOptions, dmin: int,
               max_disparity: int, pool) -> tuple[np.ndarray, np.ndarray]:
    """The grey pair, (H, W, 1) uint8, with the right view's brightness made the left's
    (:func:`.equalize.equalize`, its first pass :func:`_brightness_blind`)."""
    grey_l, grey_r = grey(left), grey(right)
    threads = o.threads or numba.get_num_threads()

    def first_pass(l_img, r_img, n, *, min_disparity, left_mask, right_mask):
        return _brightness_blind(l_img, r_img, n, min_disparity, left_mask, right_mask,
                                 threads, pool)

    grey_r = equalize(grey_l, grey_r, lmask, rmask, dmin, max_disparity, first_pass)
    return grey_l[:, :, None], grey_r[:, :, None]


def _saturated(left: np.ndarray, right: np.ndarray, o: BirchfieldOptions
               ) -> tuple[np.ndarray, int] | None:
    """``(codes, slack)`` of the pair's saturated pixels (:mod:`.saturation`) when the
    programme compares grey levels (with or without the edge prefilter, whose Sobel reads the
    neighbours and adds up to ``edge_cap``: ``slack`` in doubled grey levels), else None."""
    if (not o.censor_saturated or o.color != "gray" or o.prefilter == "highpass"
            or o.normalize_window):
        return None
    edges = o.prefilter == "edges"
    codes = saturation_codes(grey(left), grey(right), neighbours=edges)
    return None if codes is None else (codes, 2 * int(round(o.edge_cap)) if edges else 0)


def _brightness_blind(grey_l, grey_r, max_disparity, dmin, lmask, rmask, threads, pool
                      ) -> np.ndarray:
    """The equalisation's first pass: the programme of :data:`EQUALIZE_FIRST_PASS` on the
    locally normalised grey images with edges, nothing after it (the fit trims its own
    outliers). (H, W) float32 disparities, NaN = no match."""
    o = EQUALIZE_FIRST_PASS
    images = [with_edges(normalize(g, m, *o.normalization), o.edge_cap)[:, :, None]
              for g, m in ((grey_l, lmask), (grey_r, rmask))]
    params = _kernel_params(o, images[0], dmin, max_disparity, threads)
    idx, _ = _match(*images, lmask, rmask, pool=pool, **params)
    disp = idx.astype(np.float32)
    disp += np.float32(dmin)
    disp[idx < 0] = np.nan
    return disp


def _kernel_params(o: BirchfieldOptions, left: np.ndarray, dmin: int, max_disparity: int,
                   threads: int) -> dict[str, Any]:
    """The matching kernels' parameters (:func:`_match`) in their doubled integer units.

    The paper's single-pixel kernels (colour costs, the pruned search) sum no window and have
    no slant step; their rows must stay exact in float32 (StereoError if too wide)."""
    rx, ry = o.cost_window[0] // 2, o.cost_window[1] // 2
    slant = o.slant_penalty
    if o.single_pixel:
        rx, ry, slant = 0, 0, None
    aggregated = (rx, ry) != (0, 0) or slant is not None
    channels = left.shape[2] if o.color == "sum" else 1  # summed by the cost
    units = 2 * channels  # the kernels count in doubled grey levels
    occ = int(round(o.occlusion_penalty * units))
    if o.search == "exact" and not aggregated:
        _check_exact_width(left.shape[1], channels, occ)
    smooth = o.column_smoothing
    return dict(dmin=dmin, nd=max_disparity + 1, occ=occ,
                rew=int(round(o.match_reward * units)), combine_max=o.color == "max",
                mode=DP_EXACT if o.search == "exact" else DP_PRUNED, threads=threads,
                rx=rx, ry=ry, slant=-1 if slant is None else int(round(slant * units)),
                aggregated=aggregated, paper_postprocess=o.postprocess == "paper",
                smooth=None if smooth is None else tuple(int(round(p * units)) for p in smooth))


def _reject_right_to_left(masked, reject, idx, matched, masks, grey_r, o, dmin, pool,
                          params, saturated=None) -> None:
    """The left-right check: match the mirrored, swapped pair (its "left" is the mirrored
    right image) and reject (in ``masked``/``reject``) the left answers more than one pixel
    from the right view's."""
    (ml, mr), (lmask, rmask) = matched, masks
    textured_r = rewarded(texture_strength(grey_r), o.reward_texture)
    idx_r, state_r = _match(mr[:, ::-1], ml[:, ::-1], rmask[:, ::-1], lmask[:, ::-1],
                            textured=None if textured_r is None else textured_r[:, ::-1],
                            pool=pool, saturated=None if saturated is None else (
                                np.ascontiguousarray(saturated[0][::-1, :, ::-1]),
                                saturated[1]), **params)
    idx_r = np.where(state_r >= BORDER, -1, idx_r)
    idx_r = np.ascontiguousarray(idx_r[:, ::-1])
    add_rejections(masked, reject, left_right_mismatch(np.where(reject, -1, idx), idx_r,
                                                       dmin, 1))


def _finish(disp, greys, sub, rmask, o: BirchfieldOptions, dmin: int, max_disparity: int,
            pool, strips) -> np.ndarray:
    """The steps after the left-right check, on the map ``disp`` (disparities): the
    photo-consistency check, the iterated sub-pixel steps, the consensus median, the speckle
    filter, the clamp to the window and the partners' validity."""
    if o.photo_check > 0:  # before the speckle filter, which removes what it leaves isolated
        disp[photo_inconsistent(*greys, disp, o.photo_check)] = np.nan
    if o.subpixel in ("gradient", "parabola"):
        disp = refine(disp, *sub, o.subpixel, o.subpixel_radius)
    if o.consensus_size > 0:
        replace_outliers(disp, o.consensus_size, dmin, max_disparity, o.speckle_range,
                         pool=pool, strips=strips)
    if o.speckle_size > 0:
        remove_speckles(disp, o.speckle_size, o.speckle_range, pool=pool, threads=len(strips))
    disp = clip_to_window(disp, dmin, max_disparity)
    # The median and the sub-pixel steps move disparities after matching: one may now point
    # into the right image's fill or past its edge, which the programme itself never matches.
    reject_invalid_partners(disp, rmask, dmin + max_disparity)
    return disp


def _match(left, right, lmask, rmask, *, dmin, nd, occ, rew, combine_max, mode, threads,
           rx, ry, slant, aggregated, paper_postprocess, smooth=None, textured=None, pool=None,
           saturated=None):
    """Scanline matching (+ the paper's postprocessing) -> ``(index, state)``: int32 window
    indices (-1 = no match) and the pixel states of :mod:`.birchfield.common.states`; the
    default matcher runs on ``pool``'s threads (None: its own). ``saturated``: censored
    pixels (:func:`_saturated`), for the window-summed programme only."""
    lm = np.ascontiguousarray(left)
    rm = np.ascontiguousarray(right)
    lk, rk = np.ascontiguousarray(lmask), np.ascontiguousarray(rmask)
    if smooth is not None:
        out = match_image_vertical(lm[:, :, 0], rm[:, :, 0], lk, rk, dmin, nd, occ, rew,
                                   p1=smooth[0], p2=smooth[1], scale=SMOOTHING_SCALE,
                                   slant=slant, textured=textured)
        idx, state = out["disp"], out["state"]
    elif aggregated or (mode == DP_EXACT and not combine_max and lm.shape[2] == 1):
        # the matcher's threads set -1 on the pixels without a partner (as below), unless the
        # paper's postprocessing needs the dense map first
        out = match_image_aggregated(lm[:, :, 0], rm[:, :, 0], lk, rk, dmin, nd, occ, rew, rx,
                                     ry, slant=slant, textured=textured, threads=threads,
                                     pool=pool, keep_unmatched=paper_postprocess,
                                     saturated=saturated)
        if not paper_postprocess:
            return out["disp"], out["state"]
        idx, state = out["disp"], out["state"]
    else:
        idx, state = match_image(lm, rm, lk, rk, dmin, nd, occ, rew, combine_max=combine_max,
                                 mode=mode, threads=threads)
    # The dense map (border strip and occlusions filled as in the reference code) feeds the
    # postprocessing; pixels without a possible partner are removed afterwards.
    if paper_postprocess:
        idx = paper_steps.postprocess(idx, lm, nd)
    idx[state >= BORDER] = -1
    return idx, state


def _check_exact_width(width: int, channels: int, occ: int) -> None:
    limit = max_exact_width(channels, occ)
    if width > limit:
        raise StereoError(f"image width {width} exceeds {limit}, the widest row whose scanline "
                          f"costs stay exact ({channels} channel(s) summed, occlusion penalty "
                          f"{occ / 2 / channels:g}); crop or downscale the pair")
