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

Defaults of :func:`birchfield` were chosen by measurement: on calibrated real photographs
through the whole pose-based path (``bench/real_multiview.py``, results and the held-out pairs
in bench/results/real_multiview.md) and on the Middlebury pairs (``bench/stereo.py``,
bench/results/stereo.md). What changed from the paper's matcher (:data:`PAPER_OPTIONS`
restores it) and why:

- ``cost_window=(1, 3)``: dissimilarities summed over three rows tie neighbouring scanlines
  together (the paper's rows streak); wider windows blurred depth edges without gaining;
- ``slant_penalty=20``: the paper charges a full occlusion for every one-pixel disparity step,
  so slanted and curved surfaces became staircases or were lost; a cheaper step that needs
  no intensity variation keeps them (5 let the programme creep into occluded strips; 10 let
  a thin object's top ramp down across the table beside it, 24 mm too wide on the mock table's
  book, while 20 keeps its edge and costs little on the real rings:
  bench/results/real_multiview_slant20.md);
- ``reward_texture=0.5``: matching a pixel without texture earns no reward, so the programme
  no longer bends its path to match a black gap at a wrong disparity and then declares the
  textured column beside it occluded (the temple's lost column);
- ``texture_threshold=1.0``: no disparity on flat pixels unless the textured pixels on both
  sides of them on the row agree (a plain wall between two edges is kept, a background or a
  gap is not): the main source of points outside the object on real photographs. It costs
  answers on the large flat areas of Middlebury's Tsukuba and Venus (bad-2 counts a missing
  answer as wrong), most of which ``column_support`` gives back; ``texture_threshold=0``
  gives a dense map;
- ``column_support=True``: a flat run that its row cannot confirm (no textured pixel on one
  side, e.g. a flat stretch starting at the image's edge) keeps its disparity when the
  textured pixels above and below it in its column agree with it: the texture rule's misses
  on Middlebury were mostly correct answers of this kind (Venus bad-2 4.6 % -> 2.8 %, the
  640x480 synthetic table 1.9 % -> 1.1 %), while gaps and backgrounds, which their columns do
  not confirm either, still get NaN (bench/results/real_multiview_consistency.md);
- ``consensus_size=9``: an answer more than ``speckle_range`` from the median answer of the
  9x9 square around it takes that median: streaks a few rows high and blobs that disagree
  with their surface (the programme decides each scanline on its own) are replaced, at a
  uint8 median's cost (Cones 8.2 % -> 7.6 %; 7 and 11 measured in
  bench/results/stereo_consistency.md);
- ``prefilter="edges"``, ``edge_cap=12``: the programme matches ``I + clip(Sobel_x(I), -12,
  12)`` instead of the intensities ``I`` (a prefilter like SGBM's, whose cost adds a
  dissimilarity of clipped horizontal Sobels to that of the intensities): a stretch of
  background beside a nearer object then no longer matches as cheaply at the object's
  disparity, and blobs at a wrong disparity on weakly textured surfaces go (with cap 10:
  Cones bad-2 7.6 % -> 5.0 %, Venus 2.8 % -> 1.1 %; on the real rings points outside the box
  19 % -> 11 %, held out 15 % -> 6 %, cross-pair median distance down a quarter:
  bench/results/stereo_accuracy.md). Caps 10-20 are within 0.1 pt of each other on the
  tuning pairs; the gradient alone (no ``I``), a Laplacian, a 5x5 Sobel or a subtracted
  Sobel are worse. It costs about 0.3 ms per pair. The sub-pixel steps still fit the
  intensities. Grey only;
- ``occlusion_margin=5``: a pixel is declared hidden by a nearer one only when its
  right-image position lies 5 pixels (not 1) beyond the nearer pixel's: what the margin of 1
  removed beside a depth edge was mostly visible background, declared hidden by a foreground
  that the programme had carried a pixel or two past its outline (Cones bad-2 -0.3 pt, the
  rings' density back up 2 pt with the same share outside);
- ``speckle_size=100``: small islands of disparity are removed as SGBM does;
- ``postprocess="median"`` (``True``): a 5x5 median of the sub-pixel map replaces the paper's
  propagation and mode filters, which the summed costs made unnecessary (``"paper"`` keeps
  them);
- ``subpixel="fast"``: one gradient step over 5x5 (one small kernel and whole-image box
  sums), a few percent of the match time, instead of the iterated same-surface refinement;
- ``match_reward=6`` (the paper's 5): the edge image has more contrast than the intensities,
  so a match costs more and earns a little more to stay worth making (Cones 4.66 % -> 4.54 %,
  the rings' density +2 pt, cross-pair median distance on the temple 1.75 -> 1.55 mm; the
  held-out share outside 6.1 -> 6.5 %, SGBM 15.2 %);
- unchanged: ``occlusion_penalty=25`` (the paper's), ``color="gray"``,
  ``occlusions="nan"`` (a hole is cheaper than a false point in a cloud), ``lr_check=False``
  (twice the time), ``search="exact"``;
- ``column_smoothing=None`` (off): smoothing the programme's costs along the columns
  (one semi-global pass down and one up, :mod:`.birchfield.vertical`) before each row's
  programme removes the streaks the rows decide alone (Venus bad-2 2.8 % -> 1.0 %, below
  SGBM's 1.7 %; the synthetic table 1.0 % -> 0.2 %), but it spreads foreground disparities
  into the dark gaps and backgrounds of real photographs (more points outside the temple's box)
  and the matching takes about twice as long (bench/results/stereo_consistency.md,
  bench/results/real_multiview_column_smoothing.md);
- ``photo_check=0`` (off): rejecting matches whose views do not look alike removes the
  foreground fattening at tall edges on clean images (the mock table's crate: 11-13 mm too
  wide -> within 3.7 mm with 4 grey levels), but on real photographs correct matches
  differ by as much (Middlebury bad-2 4.8 % -> 9.9 % at 4, 5.3 % at 12): only callers that
  know their images are photometrically clean turn it on (:data:`CLEAN_PHOTO_CHECK`, the
  demo's ideal profile; bench/results/footprint.md).
"""

from __future__ import annotations

import logging

import cv2
import numba
import numpy as np

from armstereo.errors import StereoError
from armstereo.reconstruct.birchfield import dp_pruned as _dp
from armstereo.reconstruct.birchfield.aggregate import match_image_aggregated
from armstereo.reconstruct.birchfield.dp_exact import max_exact_width
from armstereo.reconstruct.birchfield.matcher import DP_EXACT, DP_PRUNED, match_image
from armstereo.reconstruct.birchfield.postprocess import postprocess as _postprocess
from armstereo.reconstruct.birchfield.refine import (
    gradient_terms,
    left_right_mismatch,
    refine_gradient,
    refine_parabola,
    row_rejects,
)
from armstereo.reconstruct.birchfield.vertical import match_image_vertical
from armstereo.reconstruct.consensus import replace_outliers
from armstereo.reconstruct.speckles import remove_speckles
from armstereo.reconstruct.strips import each_strip, row_strips, thread_pool

log = logging.getLogger(__name__)

METHODS = ("birchfield", "sgbm")
COLOR_MODES = ("gray", "sum", "max")
SUBPIXEL_MODES = ("fast", "none", "parabola", "gradient")
SEARCH_MODES = ("exact", "pruned")
OCCLUSION_MODES = ("nan", "fill")
POSTPROCESS_MODES = ("median", "paper", "none")

# Defaults chosen on the benchmarks (module doc, "Defaults")
COST_WINDOW = (1, 3)  # (width, height) of the summed-cost window
SLANT_PENALTY = 20.0  # grey levels, for a one-pixel disparity step
TEXTURE_THRESHOLD = 1.0  # grey levels per pixel, mean |horizontal gradient| over the window
TEXTURE_WINDOW = 5
INPUT_HALO = 1 + TEXTURE_WINDOW // 2  # rows the texture map's Sobel and box filter reach
REWARD_TEXTURE = 0.5  # grey levels per pixel: matching flatter pixels earns no reward
MATCH_REWARD = 6.0  # grey levels (the paper's 5 on intensities; 5.5, 6.5 measured)
PREFILTER_MODES = ("none", "highpass", "edges")
PREFILTER = "edges"
# grey levels: "edges" adds the horizontal Sobel clipped to +-this (10, 12, 15, 20 measured:
# bench/results/stereo_accuracy.md)
EDGE_CAP = 12.0
PREFILTER_SIGMA = 8.0  # px: slower brightness changes than this are removed
PREFILTER_GAIN = 2.0  # contrast of what is left (the penalties are in grey levels)
SPECKLE_SIZE = 100  # pixels
SPECKLE_RANGE = 2.0  # pixels of disparity
# column_smoothing: the smoothed costs weigh as much as this many single-pixel costs when
# the penalties are scaled (2 and 4 measured: bench/results/stereo_consistency.md)
SMOOTHING_SCALE = 3
CONSENSUS_SIZE = 9  # pixels: side of the consensus median's square
MEDIAN_SIZE = 5
OCCLUSION_MARGIN = 5.0  # pixels: see _hidden_by_nearer (1, 2, 3, 5, 8 measured)
FLAT_TOLERANCE = 1.0  # pixels: see _unsupported
FLAT_SLOPE = 0.1  # disparity change per pixel a flat run may bridge
PHOTO_WINDOW = 3  # pixels: side of the photo-consistency check's window
# photo_check for photometrically clean views (noise ~1 grey level, same exposure and
# response in both), chosen on the mock table scene (bench/results/footprint.md)
CLEAN_PHOTO_CHECK = 4.0
PHOTO_EDGE_REACH = 16  # pixels along the row: how far from a depth jump fattening reaches
PHOTO_EDGE_JUMP = 2.0  # pixels of disparity: a jump a foreground can be carried across

# The paper's matcher as published (single-pixel costs, its postprocessing, nothing added)
PAPER_OPTIONS = dict(cost_window=(1, 1), slant_penalty=None, postprocess="paper",
                     texture_threshold=0.0, reward_texture=0.0, speckle_size=0,
                     subpixel="none", occlusions="fill", column_support=False,
                     consensus_size=0, prefilter="none", match_reward=5)

# gradient refinement passes: averaged bad-2 3.79 % with 1, 3.72 % with 2, 3.68 % with 3
SUBPIXEL_WINDOW = 5  # "fast" sub-pixel step: window side (pixels)
SUBPIXEL_MIN_GRADIENT = 1e-3  # sum of squared gradients below which no step is taken
SUBPIXEL_ITERATIONS = 2
SUBPIXEL_MAX_SHIFT = 1.0


def birchfield(left: np.ndarray, right: np.ndarray, max_disparity: int, *,
               min_disparity: int = 0, occlusion_penalty: float = 25,
               match_reward: float = MATCH_REWARD,
               color: str = "gray", postprocess: bool | str = True, occlusions: str = "nan",
               lr_check: bool = False, subpixel: str = "fast", subpixel_radius: int = 5,
               search: str = "exact", left_mask: np.ndarray | None = None,
               right_mask: np.ndarray | None = None, threads: int | None = None,
               cost_window: tuple[int, int] = COST_WINDOW,
               slant_penalty: float | None = SLANT_PENALTY,
               texture_threshold: float = TEXTURE_THRESHOLD,
               speckle_size: int = SPECKLE_SIZE, speckle_range: float = SPECKLE_RANGE,
               reward_texture: float = REWARD_TEXTURE, prefilter: str = PREFILTER,
               prefilter_sigma: float = PREFILTER_SIGMA,
               prefilter_gain: float = PREFILTER_GAIN, edge_cap: float = EDGE_CAP,
               occlusion_margin: float = OCCLUSION_MARGIN,
               photo_check: float = 0.0, column_support: bool = True,
               consensus_size: int = CONSENSUS_SIZE,
               column_smoothing: tuple[float, float] | None = None) -> np.ndarray:
    """Birchfield-Tomasi pixel-to-pixel stereo (ICCV'98), made robust for real photographs.

    The algorithm: the sampling-insensitive symmetric dissimilarity, one dynamic programme per
    scanline over match sequences (an occlusion costs ``occlusion_penalty`` once, each match
    earns ``match_reward``, occlusions only next to intensity variation; grey-level units),
    then postprocessing. :data:`PAPER_OPTIONS` gives the paper's plain matcher; the defaults
    add (see "Defaults" in the module doc for why):

    - ``cost_window`` ``(width, height)``: node costs are dissimilarities summed over this
      window at the same disparity (penalties scale with it); ``(1, 1)`` is the paper's.
      Summing over rows ties neighbouring scanlines together (no streaks).
    - ``slant_penalty``: a one-pixel disparity step costs this instead of an occlusion and
      needs no intensity variation (slanted surfaces); None = the paper's model.
    - ``texture_threshold``: a pixel is flat where the mean absolute horizontal gradient over
      a 5x5 window is below this (grey levels per pixel); a flat pixel keeps its disparity
      only if the nearest textured pixels left and right of it on the row agree with it
      (:func:`_unsupported`), else NaN: no invented depth on backgrounds and gaps. 0 = off.
    - ``reward_texture``: matching a left pixel flatter than this earns no ``match_reward``,
      so the programme gains nothing by matching featureless pixels. 0 = reward everywhere.
    - ``column_support``: a flat pixel its row does not confirm is still kept when the
      nearest textured pixels above and below it in its column confirm it (the same test
      along the column); False = rows only.
    - ``consensus_size``: an answer differing by more than ``speckle_range`` from the median
      answer over this square around it is replaced by that median
      (:func:`.consensus.replace_outliers`); 0 = off. Odd, >= 3.
    - ``column_smoothing``: ``(p1, p2)`` grey levels: the programme's node costs are first
      smoothed along each column, down and up, as semi-global matching does along one line
      (a one-disparity change between rows costs ``p1``, a larger one ``p2``), and each row's
      programme runs on the sum (penalties scaled by SMOOTHING_SCALE; replaces
      ``cost_window``'s summing; one thread, an (H, W, disparities) float32 volume). Needs
      ``color="gray"`` and ``search="exact"``. None = off.
    - ``speckle_size``/``speckle_range``: NaN on connected regions of fewer than
      ``speckle_size`` pixels whose disparity differs by more than ``speckle_range`` from
      their surroundings (OpenCV's ``filterSpeckles``, as SGBM does); 0 = off.
    - ``postprocess``: ``"median"`` (True): 5x5 median of the sub-pixel map; ``"paper"``:
      the paper's propagation across scanlines and mode filters; ``"none"`` (False).
    - ``subpixel``: ``"fast"``: one Lucas-Kanade step over a 5x5 window, each pixel at its own
      disparity (:func:`_gradient_step`); ``"gradient"`` (iterated, over a window of the same
      surface) or ``"parabola"`` (windowed SSD at d-1, d, d+1), both with a
      ``2 * subpixel_radius + 1`` window; ``"none"``.
    - ``search``: ``"exact"`` solves each scanline's programme exactly in O(width x
      disparities); ``"pruned"`` is the reference code's heuristic search (about 18x slower).
    - ``color``: ``"gray"`` matches the BGR2GRAY image; ``"sum"``/``"max"`` combine
      per-channel dissimilarities. ``"pruned"``, ``"sum"`` and ``"max"`` run the paper's
      single-pixel kernels: ``cost_window`` and ``slant_penalty`` do not apply.
    - ``occlusions``: ``"nan"`` leaves NaN on left pixels the final map itself shows hidden by
      a nearer pixel (their right-image position at least ``occlusion_margin`` pixels right
      of that of a pixel right of them, :func:`_hidden_by_nearer`); ``"fill"`` keeps the
      paper's background fill.
    - ``lr_check``: also match right-to-left (mirrored pair) and reject disparities that differ
      by more than one pixel. Matching takes twice as long.
    - ``threads``: the steps run on this many threads (default ``numba.get_num_threads()``):
      the matching on chunks of rows the threads take in turn, the others on strips of rows
      side by side (:mod:`.strips`, :mod:`.speckles`); the result does not depend on it. A
      second thread pays on camera-sized images (1.5-1.9x at 0.3-1.5 megapixels), much less
      on small ones (bench/results/stereo_scaling.md).
    - ``prefilter``: ``"edges"`` matches ``I + clip(Sobel_x(I), -edge_cap, edge_cap)`` of
      each grey image (3x3 horizontal Sobel, saturated to uint8; :func:`_with_edges`): the
      dissimilarity then also compares the images' horizontal gradients, as SGBM's prefiltered
      cost does, so depth jumps land on the objects' outlines instead of carrying the nearer
      surface past them. ``"highpass"`` matches ``prefilter_gain * (I - G * I) + 128`` of
      each grey image (``G``: a Gaussian of ``prefilter_sigma`` px, normalised over the valid
      pixels), so brightness that changes slowly across the image (vignetting, exposure) does
      not shift matches; ``"none"`` matches the intensities as the paper does. Grey matching
      only: ``"edges"`` does not apply to ``color="sum"``/``"max"``, ``"highpass"`` is
      refused there.
    - ``photo_check``: NaN where the final match does not look alike: the grey difference
      ``|L(x) - R(x - d(x))|`` (right image interpolated, each pixel at its own disparity, so
      a window at a depth edge compares each surface with itself) averaged over the 3x3
      answered pixels around it exceeds this many grey levels (:func:`_photo_inconsistent`).
      Only pixels within 16 px along the row of a disparity jump of more than 2 px are
      tested: it removes the foreground carried across a half-occluded strip or a steep
      side, which no disparity test can tell from the foreground. Only for photometrically
      clean views (:data:`CLEAN_PHOTO_CHECK`): real photographs differ by as much at correct
      matches. 0 = off (default).

    Every returned disparity lies in ``[min_disparity, min_disparity + max_disparity]``. Left
    pixels whose partner ``x - d`` (nearest pixel) would lie outside the right image (the strip
    ``x < d``) or on a masked right pixel are NaN.

    Raises StereoError for unusable input (sizes, dtype, disparity range, masks, options).
    """
    postprocess = _postprocess_mode(postprocess)
    _check_options(color=color, subpixel=subpixel, search=search, occlusions=occlusions,
                   postprocess=postprocess)
    left, right, lmask, rmask = _prepare(left, right, max_disparity, min_disparity, left_mask,
                                         right_mask)
    if threads is not None and threads < 1:
        raise StereoError(f"threads must be >= 1, got {threads}")
    if occlusion_penalty < 0 or match_reward < 0 or subpixel_radius < 0:
        raise StereoError(f"occlusion_penalty ({occlusion_penalty}), match_reward "
                          f"({match_reward}) and subpixel_radius ({subpixel_radius}) must be >= 0")
    rx, ry = _window_radii(cost_window)
    if slant_penalty is not None and slant_penalty < 0:
        raise StereoError(f"slant_penalty must be >= 0 or None, got {slant_penalty}")
    if not (texture_threshold >= 0 and speckle_size >= 0 and speckle_range >= 0):  # NaN too
        raise StereoError(f"texture_threshold ({texture_threshold}), speckle_size "
                          f"({speckle_size}) and speckle_range ({speckle_range}) must be >= 0")
    if consensus_size != 0 and (consensus_size < 3 or consensus_size % 2 == 0):
        raise StereoError(f"consensus_size must be 0 (off) or odd and >= 3, got {consensus_size}")
    if not occlusion_margin >= 0:
        raise StereoError(f"occlusion_margin must be >= 0 pixels, got {occlusion_margin}")
    if not photo_check >= 0:
        raise StereoError(f"photo_check must be >= 0 grey levels, got {photo_check}")
    smooth = _smoothing(column_smoothing)
    if smooth is not None and (color != "gray" or search != "exact"):
        raise StereoError('column_smoothing needs color="gray" and search="exact"')
    if color != "gray" or search != "exact":  # only the paper's single-pixel kernels
        rx, ry, slant_penalty = 0, 0, None
    aggregated = (rx, ry) != (0, 0) or slant_penalty is not None
    if prefilter not in PREFILTER_MODES:
        raise StereoError(f"prefilter={prefilter!r} is not one of {', '.join(PREFILTER_MODES)}")
    if prefilter == "highpass" and color != "gray":
        raise StereoError('prefilter="highpass" works on grey matching only (color="gray")')
    if prefilter == "edges" and not edge_cap > 0:
        raise StereoError(f"edge_cap must be > 0 grey levels, got {edge_cap}")
    channels = left.shape[2] if color == "sum" else 1  # summed by the cost
    units = 2 * channels  # the kernels count in doubled grey levels
    occ = int(round(occlusion_penalty * units))
    if search == "exact" and not aggregated:
        _check_exact_width(left.shape[1], channels, occ)
    n_threads = threads or numba.get_num_threads()
    params = dict(dmin=min_disparity, nd=max_disparity + 1, occ=occ,
                  rew=int(round(match_reward * units)), combine_max=color == "max",
                  mode=DP_EXACT if search == "exact" else DP_PRUNED, threads=n_threads,
                  rx=rx, ry=ry, slant=-1 if slant_penalty is None else int(round(
                      slant_penalty * units)), aggregated=aggregated,
                  paper_postprocess=postprocess == "paper",
                  smooth=None if smooth is None else tuple(int(round(p * units)) for p in smooth))
    # every step but the matching (which has its own threads) runs on strips of rows side by
    # side where it can (the speckle filter on strips of its own)
    strips = row_strips(left.shape[0], n_threads)
    with thread_pool(n_threads) as pool:
        # the photo-consistency check and the sub-pixel steps read the unfiltered grey images
        grey_l, grey_r, gl, gr, flat, textured_l = _inputs(
            pool, strips, left, right,
            edge_cap=edge_cap if prefilter == "edges" and color == "gray" else None,
            flat_below=texture_threshold, reward_from=reward_texture)
        if prefilter == "highpass":
            gl = _highpass(grey_l, lmask, prefilter_sigma, prefilter_gain)
            gr = _highpass(grey_r, rmask, prefilter_sigma, prefilter_gain)
        # the sub-pixel steps fit intensities: the edge image's clipping and saturation are not
        # a shifted copy of the other view's, and its Sobel sees the image border
        sub_l, sub_r = (grey_l, grey_r) if prefilter == "edges" else (gl, gr)
        ml, mr = (gl[:, :, None], gr[:, :, None]) if color == "gray" else (left, right)
        idx, state = _match(ml, mr, lmask, rmask, textured=textured_l, pool=pool, **params)
        masked, reject = _masked_map(pool, strips, sub_l, sub_r, idx, min_disparity,
                                     fast=subpixel == "fast", median=postprocess == "median",
                                     flat=flat, columns=column_support,
                                     hidden=occlusion_margin if occlusions == "nan" else None)
        if lr_check:
            textured_r = _rewarded(_texture_strength(grey_r), reward_texture)
            idx_r, state_r = _match(mr[:, ::-1], ml[:, ::-1], rmask[:, ::-1], lmask[:, ::-1],
                                    textured=None if textured_r is None else textured_r[:, ::-1],
                                    pool=pool, **params)
            # mirrored, swapped pair: its "left" is the mirrored right image
            idx_r = np.where(state_r >= _dp.BORDER, -1, idx_r)
            idx_r = np.ascontiguousarray(idx_r[:, ::-1])
            _reject(masked, reject, left_right_mismatch(np.where(reject, -1, idx), idx_r,
                                                        min_disparity, 1))
        disp = masked
        disp += np.float32(min_disparity)
        if photo_check > 0:  # before the speckle filter, which removes what it leaves isolated
            disp[_photo_inconsistent(grey_l, grey_r, disp, photo_check)] = np.nan
        if subpixel in ("gradient", "parabola"):
            whole = np.rint(disp)
            if subpixel == "gradient":
                disp = refine_gradient(sub_l.astype(np.float32), sub_r.astype(np.float32),
                                       whole, subpixel_radius, SUBPIXEL_ITERATIONS,
                                       SUBPIXEL_MAX_SHIFT)
            else:
                disp = refine_parabola(sub_l.astype(np.float32), sub_r.astype(np.float32),
                                       whole, subpixel_radius)
        if consensus_size > 0:
            replace_outliers(disp, consensus_size, min_disparity, max_disparity, speckle_range,
                             pool=pool, strips=strips)
        if speckle_size > 0:
            remove_speckles(disp, speckle_size, speckle_range, pool=pool, threads=len(strips))
        disp = _clip_to_window(disp, min_disparity, max_disparity)
        # The median and the sub-pixel steps move disparities after matching: one may now point
        # into the right image's fill or past its edge, which the programme itself never matches.
        _reject_invalid_partners(disp, rmask, min_disparity + max_disparity)
    return disp


def _inputs(pool, strips: list[tuple[int, int]], left: np.ndarray, right: np.ndarray, *,
            edge_cap: float | None, flat_below: float, reward_from: float) -> tuple:
    """What the programme and the checks start from, on ``strips`` of rows side by side:
    ``(grey_l, grey_r, matched_l, matched_r, flat, textured)``, the (H, W) uint8 grey images,
    the images the programme matches (the edge images, :func:`_with_edges`, when
    ``edge_cap`` is given; else the grey ones), the left image's flat pixels (texture
    strength below ``flat_below``; None if 0) and those that earn the match reward (strength
    at least ``reward_from``, :func:`_rewarded`; None if 0)."""
    H, W = left.shape[:2]
    grey = np.empty((2, H, W), np.uint8)
    matched = grey if edge_cap is None else np.empty((2, H, W), np.uint8)
    flat = np.empty((H, W), np.bool_) if flat_below > 0 else None
    textured = np.empty((H, W), np.bool_) if reward_from > 0 else None
    each_strip(pool, strips, _input_rows, left, right, edge_cap, flat_below, reward_from, grey,
               matched, flat, textured)
    return grey[0], grey[1], matched[0], matched[1], flat, textured


def _input_rows(first: int, stop: int, left: np.ndarray, right: np.ndarray,
                edge_cap: float | None, flat_below: float, reward_from: float,
                grey: np.ndarray, matched: np.ndarray, flat: np.ndarray | None,
                textured: np.ndarray | None) -> None:
    """Rows ``first .. stop - 1`` of :func:`_inputs`, filtered from INPUT_HALO rows more on
    each side (the filters' own border only touches rows that are dropped)."""
    a, b = max(0, first - INPUT_HALO), min(left.shape[0], stop + INPUT_HALO)
    rows, keep = slice(first, stop), slice(first - a, stop - a)
    for i, img in enumerate((left, right)):
        g = _grey(img[a:b])
        grey[i, rows] = g[keep]
        if edge_cap is not None:
            matched[i, rows] = _with_edges(g, edge_cap)[keep]
        if i == 0 and (flat is not None or textured is not None):
            # one texture map of the left image serves both thresholds
            strength = _texture_strength(g)[keep]
            if flat is not None:
                np.less(strength, flat_below, out=flat[rows])
            if textured is not None:
                textured[rows] = _rewarded(strength, reward_from)  # the rule in one place


def _masked_map(pool, strips, gl, gr, idx, dmin, *, fast, median, flat, columns, hidden):
    """The map in window units with every rejection before the left-right check: sub-pixel
    step, median, NaN on unmatched pixels, on flat pixels their surroundings do not confirm
    (:func:`_unsupported`) and on pixels a nearer one hides (:func:`_hidden_by_nearer`, with
    the margin ``hidden``; None = not tested). ``gl``/``gr``: the images the sub-pixel step
    fits. Returns ``(masked, reject)``: float32 (NaN where rejected) and the bool rejections."""
    masked = np.empty(idx.shape, np.float32)
    reject = np.empty(idx.shape, np.bool_)
    each_strip(pool, strips, _first_pass, gl, gr, idx, dmin, fast, median, masked, reject)
    if flat is not None or hidden is not None:
        _flat_and_hidden(masked, reject, flat, FLAT_TOLERANCE, columns, hidden, apply=True,
                         pool=pool, strips=strips)
    return masked, reject


def _first_pass(first, stop, gl, gr, idx, dmin, fast, median, masked, reject):
    """Rows ``first .. stop - 1`` of :func:`_masked_map` up to the test of the flat pixels:
    the windows of the sub-pixel step and the median reach beyond the strip, so they run on
    a few rows more."""
    H = idx.shape[0]
    halo = (SUBPIXEL_WINDOW // 2 if fast else 0) + (MEDIAN_SIZE // 2 if median else 0)
    a, b = max(0, first - halo), min(H, stop + halo)
    part = idx[a:b]
    dense = part.astype(np.float32)  # _match has set -1 on every pixel it rejects
    if fast:
        dense += _gradient_step(gl[a:b], gr[a:b], part, dmin)
    rows, rej = masked[first:stop], reject[first:stop]
    np.less(idx[first:stop], 0, out=rej)
    if median and (a, b) == (first, stop):  # the whole image: straight into the map
        _median(dense, rows)
    else:
        if median:
            dense = _median(dense)
        np.copyto(rows, dense[first - a:stop - a])
    np.copyto(rows, np.float32(np.nan), where=rej)  # NaN where rejected so far


def _reject(masked: np.ndarray, reject: np.ndarray, new: np.ndarray) -> None:
    """Add ``new`` to the (H, W) bool ``reject`` and set NaN there in ``masked`` (in place)."""
    reject |= new
    masked[new] = np.nan


def _median(dense: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
    """MEDIAN_SIZE median of the float32 map (into ``out`` if given, same shape). Unmatched
    pixels (-1) take part like the others; the caller sets them NaN afterwards."""
    return cv2.medianBlur(dense, MEDIAN_SIZE, dst=out)


def _photo_inconsistent(left: np.ndarray, right: np.ndarray, disp: np.ndarray,
                        threshold: float) -> np.ndarray:
    """Left pixels whose match does not look alike: the mean absolute grey difference
    ``|L(x) - R(x - d(x))|`` (right image linearly interpolated), each pixel at its own
    disparity, averaged over the PHOTO_WINDOW square of answered pixels, exceeds
    ``threshold`` grey levels."""
    H, W = disp.shape
    ok = np.isfinite(disp)
    xr = np.arange(W, dtype=np.float32)[None, :] - np.where(ok, disp, np.float32(0))
    yr = np.broadcast_to(np.arange(H, dtype=np.float32)[:, None], (H, W))
    warped = cv2.remap(right.astype(np.float32), xr, np.ascontiguousarray(yr),
                       cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
    err = np.where(ok, np.abs(left.astype(np.float32) - warped), np.float32(0))
    win = (PHOTO_WINDOW, PHOTO_WINDOW)
    total = cv2.boxFilter(err, -1, win, normalize=False)
    count = cv2.boxFilter(ok.astype(np.float32), -1, win, normalize=False)
    return ok & (total > np.float32(threshold) * count) & _near_depth_jump(disp)


def _near_depth_jump(disp: np.ndarray) -> np.ndarray:
    """Pixels within PHOTO_EDGE_REACH px along their row of a disparity differing from
    theirs by more than PHOTO_EDGE_JUMP: where a foreground can be carried across its edge.
    Elsewhere a large residual is steep texture or noise, not fattening."""
    kernel = np.ones((1, 2 * PHOTO_EDGE_REACH + 1), np.uint8)
    ok = np.isfinite(disp)
    hi = cv2.dilate(np.where(ok, disp, np.float32(-np.inf)).astype(np.float32), kernel)
    lo = cv2.erode(np.where(ok, disp, np.float32(np.inf)).astype(np.float32), kernel)
    with np.errstate(invalid="ignore"):
        return (hi - disp > PHOTO_EDGE_JUMP) | (disp - lo > PHOTO_EDGE_JUMP)


def _highpass(grey: np.ndarray, mask: np.ndarray, sigma: float, gain: float) -> np.ndarray:
    """``gain * (I - local mean) + 128`` as uint8; the local mean is a Gaussian average over
    the valid pixels only, so a rectification's black fill does not darken the border."""
    if not (sigma > 0 and gain > 0):
        raise StereoError(f"prefilter_sigma ({sigma}) and prefilter_gain ({gain}) must be > 0")
    g = grey.astype(np.float32)
    w = mask.astype(np.float32)
    num = cv2.GaussianBlur(g * w, (0, 0), sigma)
    den = cv2.GaussianBlur(w, (0, 0), sigma)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = np.where(den > 1e-3, num / den, g)
    out = np.float32(gain) * (g - mean) + np.float32(128)
    return np.clip(np.rint(out), 0, 255).astype(np.uint8)


def _with_edges(grey: np.ndarray, cap: float) -> np.ndarray:
    """``I + clip(Sobel_x(I), -cap, cap)`` as uint8 (saturated): the matched image of
    ``prefilter="edges"``."""
    if not cap > 0:
        raise StereoError(f"edge_cap must be > 0 grey levels, got {cap}")
    sx = cv2.Sobel(grey, cv2.CV_16S, 1, 0, ksize=3)
    c = int(round(cap))
    np.clip(sx, -c, c, out=sx)
    return cv2.add(grey, sx, dtype=cv2.CV_8U)


def _gradient_step(left: np.ndarray, right: np.ndarray, idx: np.ndarray,
                   dmin: int) -> np.ndarray:
    """Sub-pixel offsets: one Lucas-Kanade step per pixel over a SUBPIXEL_WINDOW square.

    Each pixel contributes at its own integer disparity ``d``: the residual ``e = L(x) -
    R(x - d)`` and the symmetric gradient ``g`` (mean of both images' central differences);
    with ``L(x) ~ R(x - d - delta)`` the window's least-squares step is ``delta = -sum(g e) /
    sum(g^2)``, clamped to +-1 (0 where the window has no gradient). The per-pixel terms
    come from one kernel (:func:`gradient_terms`: the gathers at each pixel's partner cost
    numpy a pass each), the window sums from OpenCV.
    """
    # g is a small integer times 1/4 and e an integer: every term, and every window sum
    # below, is exact in float32 whatever the order
    g = np.empty(idx.shape, np.float32)
    minus_e = np.empty(idx.shape, np.float32)  # -g e, so that the window sum is -sum(g e)
    gradient_terms(left, right, np.asarray(idx, np.int32), np.int64(dmin), g, minus_e)
    win = (SUBPIXEL_WINDOW, SUBPIXEL_WINDOW)
    sgg = cv2.boxFilter(g, -1, win, dst=g, normalize=False)
    step = cv2.boxFilter(minus_e, -1, win, dst=minus_e, normalize=False)
    # no gradient, no step: where sgg is 0 (the sums are multiples of 1/16, so none lies
    # between 0 and the threshold) every g, and so the sum of g e, is 0 too: step keeps it
    np.divide(step, sgg, out=step, where=sgg > SUBPIXEL_MIN_GRADIENT)
    return np.clip(step, -SUBPIXEL_MAX_SHIFT, SUBPIXEL_MAX_SHIFT, out=step)


def _postprocess_mode(postprocess: bool | str) -> str:
    if postprocess is True:
        return "median"
    if postprocess is False:
        return "none"
    return postprocess


def _rewarded(strength: np.ndarray | None, threshold: float) -> np.ndarray | None:
    """Pixels whose match earns the reward: those with texture (None = all), from
    :func:`_texture_strength`."""
    if threshold <= 0:
        return None
    return ~(strength < threshold)


def _smoothing(column_smoothing) -> tuple[float, float] | None:
    """``(p1, p2)`` grey levels of the column pass, checked (None = off)."""
    if column_smoothing is None:
        return None
    try:
        p1, p2 = (float(v) for v in column_smoothing)
    except (TypeError, ValueError):
        raise StereoError(f"column_smoothing must be (p1, p2) or None, "
                          f"got {column_smoothing!r}") from None
    if not 0 <= p1 <= p2:
        raise StereoError(f"column_smoothing needs 0 <= p1 <= p2, got {column_smoothing!r}")
    return p1, p2


def _window_radii(cost_window) -> tuple[int, int]:
    try:
        w, h = (int(v) for v in cost_window)
    except (TypeError, ValueError):
        raise StereoError(f"cost_window must be (width, height), got {cost_window!r}") from None
    if w < 1 or h < 1 or w % 2 == 0 or h % 2 == 0:
        raise StereoError(f"cost_window sides must be odd and >= 1, got {cost_window!r}")
    return w // 2, h // 2


def _hidden_by_nearer(disp: np.ndarray, margin: float) -> np.ndarray:
    """Left pixels that a nearer pixel of the same map hides in the right view.

    ``x - d(x)`` is the pixel's right-image position; it is hidden when that lies at least
    ``margin`` pixels right of the leftmost right-image position of the pixels to its right
    (``margin = 1`` tolerates the one-pixel ties of slanted surfaces). NaN takes no part
    (and is not marked). The map itself is not changed.
    """
    hidden = np.zeros(disp.shape, np.bool_)
    _flat_and_hidden(np.array(disp, np.float32), hidden, None, 0.0, False, margin, apply=False)
    return hidden


def _unsupported(disp: np.ndarray, flat: np.ndarray, tolerance: float,
                 columns: bool = False) -> np.ndarray:
    """Flat pixels whose disparity their row's textured surroundings do not confirm.

    A flat pixel is kept only when the nearest textured pixels with a disparity to its left
    and to its right on the same row both exist, differ by at most ``tolerance`` plus
    FLAT_SLOPE per pixel between them, and its disparity lies between theirs (+-
    ``tolerance``): a plain wall between two edges of the same surface, not a gap or a
    background that the programme had to invent a disparity for. A run of flat pixels with
    a disparity next to a break (no disparity, or the image's edge) within two texture
    windows needs only the anchor at its other end. With ``columns``, a flat pixel its row
    rejects is still kept when the same test along its column (above and below it) confirms
    it. ``tolerance`` >= 0.
    """
    disp = np.ascontiguousarray(disp, np.float32)
    return _flat_and_hidden(disp, np.empty(disp.shape, np.bool_), flat, tolerance, columns,
                            None, apply=False)


def _flat_and_hidden(disp: np.ndarray, reject: np.ndarray, flat: np.ndarray | None,
                     tolerance: float, columns: bool, hidden: float | None, *, apply: bool,
                     pool=None, strips: list[tuple[int, int]] | None = None) -> np.ndarray:
    """:func:`_unsupported` of the (H, W) float32 ``disp`` (None ``flat``: not tested), with
    ``apply`` set to NaN in ``disp`` and True in ``reject`` there, then the pixels
    :func:`_hidden_by_nearer` finds with the margin ``hidden`` (None: not tested) likewise
    (in place, :func:`row_rejects`). Returns the unsupported pixels. ``strips`` of rows run
    side by side on ``pool`` (the column test first, on as many strips of columns)."""
    H, W = disp.shape
    strips = strips or [(0, H)]
    out = np.empty((H, W), np.bool_)
    kind = along = None
    if flat is not None:
        kind = np.empty((H, W), np.uint8)  # 2 * flat + finite (KIND_*)
        each_strip(pool, strips, _kinds, disp, np.ascontiguousarray(flat, np.bool_), kind)
        if columns:  # the same test along the columns, on strips of columns
            along = np.empty((H, W), np.bool_)
            each_strip(pool, row_strips(W, len(strips)), _columns, disp, kind, tolerance, along)
    each_strip(pool, strips, _rows, disp, kind, along, reject, tolerance, hidden, apply, out)
    return out


def _kinds(first: int, stop: int, disp: np.ndarray, flat: np.ndarray, kind: np.ndarray) -> None:
    """Rows ``first .. stop - 1`` of ``kind``: 2 * flat + answered (the KIND_* of
    :func:`row_rejects`)."""
    rows = kind[first:stop]
    np.isfinite(disp[first:stop], out=rows.view(np.bool_))
    rows += flat[first:stop].view(np.uint8) * np.uint8(2)


def _columns(first: int, stop: int, disp: np.ndarray, kind: np.ndarray, tolerance: float,
             along: np.ndarray) -> None:
    """Columns ``first .. stop - 1`` of the column test (``along``): the row test of
    :func:`_rows` on transposed copies (OpenCV's transpose: several times faster than
    numpy's copy of a transposed view)."""
    across = np.empty((stop - first, disp.shape[0]), np.bool_)
    _rows(0, stop - first, cv2.transpose(disp[:, first:stop]),
          cv2.transpose(kind[:, first:stop]), None, across, tolerance, None, False, across)
    along[:, first:stop] = cv2.transpose(across.view(np.uint8)).view(np.bool_)


def _rows(first: int, stop: int, disp: np.ndarray, kind: np.ndarray | None,
          along: np.ndarray | None, reject: np.ndarray, tolerance: float, hidden: float | None,
          apply: bool, out: np.ndarray) -> None:
    """Rows ``first .. stop - 1`` of :func:`_flat_and_hidden` (:func:`row_rejects`; None
    arrays: not used)."""
    no_kind = np.empty((0, 0), np.uint8)  # read only with kind
    row_rejects(disp, no_kind if kind is None else kind, out if along is None else along, reject,
                np.float64(tolerance), np.float64(FLAT_SLOPE), np.int64(2 * TEXTURE_WINDOW),
                np.float64(0.0 if hidden is None else hidden), np.bool_(kind is not None),
                np.bool_(along is not None), np.bool_(apply), np.bool_(hidden is not None),
                np.int64(first), np.int64(stop), out)


def _texture_strength(grey: np.ndarray) -> np.ndarray:
    """Mean absolute horizontal gradient over the TEXTURE_WINDOW square, grey levels per
    pixel (Sobel / 8 = central difference, smoothed): below a threshold a pixel is flat."""
    # scale 1/8 inside the filter: exact, as every Sobel sum is an integer
    gx = cv2.Sobel(grey, cv2.CV_32F, 1, 0, ksize=3, scale=1 / 8)
    np.abs(gx, out=gx)
    return cv2.blur(gx, (TEXTURE_WINDOW, TEXTURE_WINDOW), dst=gx)


def _clip_to_window(disp: np.ndarray, min_disparity: int, max_disparity: int) -> np.ndarray:
    """Sub-pixel steps may leave the searched window by a fraction: clamp them back."""
    np.clip(disp, min_disparity, min_disparity + max_disparity, out=disp)
    return disp


def _match(left, right, lmask, rmask, *, dmin, nd, occ, rew, combine_max, mode, threads,
           rx, ry, slant, aggregated, paper_postprocess, smooth=None, textured=None, pool=None):
    """Scanline matching (+ the paper's postprocessing) -> ``(index, state)``: int32 window
    indices (-1 = no match) and the states of :mod:`armstereo.reconstruct.birchfield.dp_pruned`;
    the default matcher runs on ``pool``'s threads (None: its own)."""
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
                                     pool=pool, keep_unmatched=paper_postprocess)
        if not paper_postprocess:
            return out["disp"], out["state"]
        idx, state = out["disp"], out["state"]
    else:
        idx, state = match_image(lm, rm, lk, rk, dmin, nd, occ, rew, combine_max=combine_max,
                                 mode=mode, threads=threads)
    # The dense map (border strip and occlusions filled as in the reference code) feeds the
    # postprocessing; pixels without a possible partner are removed afterwards.
    if paper_postprocess:
        idx = _postprocess(idx, lm, nd)
    idx[state >= _dp.BORDER] = -1
    return idx, state


def compute_disparity(left: np.ndarray, right: np.ndarray, max_disparity: int, *,
                      method: str = "birchfield", min_disparity: int = 0,
                      left_mask: np.ndarray | None = None, right_mask: np.ndarray | None = None,
                      **options) -> np.ndarray:
    """Disparity of the left image by ``method`` (``"birchfield"`` or ``"sgbm"``).

    Same conventions and search window for both (see the module doc); ``options`` go to
    :func:`birchfield` or :func:`sgbm`.
    """
    if method == "birchfield":
        return birchfield(left, right, max_disparity, min_disparity=min_disparity,
                          left_mask=left_mask, right_mask=right_mask, **options)
    if method == "sgbm":
        return sgbm(left, right, max_disparity, min_disparity=min_disparity,
                    left_mask=left_mask, right_mask=right_mask, **options)
    raise StereoError(f"unknown stereo method {method!r}; choose one of {', '.join(METHODS)}")


def sgbm(left: np.ndarray, right: np.ndarray, max_disparity: int, *, min_disparity: int = 0,
         block_size: int = 5, uniqueness: int = 10, speckle_window: int = 100,
         speckle_range: int = 2, lr_tolerance: int = 1, left_mask: np.ndarray | None = None,
         right_mask: np.ndarray | None = None) -> np.ndarray:
    """OpenCV StereoSGBM as a peer, in this module's conventions.

    ``numDisparities`` is ``max_disparity + 1`` rounded up to a multiple of 16; answers outside
    ``[min_disparity, min_disparity + max_disparity]`` become NaN, as do SGBM's invalid pixels
    (it answers nothing in the left band ``x < min_disparity + numDisparities - 1``).
    P1 = 8 cn bs^2, P2 = 32 cn bs^2 (OpenCV's recommended smoothness).
    """
    left, right, lmask, rmask = _prepare(left, right, max_disparity, min_disparity, left_mask,
                                         right_mask)
    if block_size < 1 or block_size % 2 == 0:
        raise StereoError(f"SGBM block_size must be odd and >= 1, got {block_size}")
    cn = left.shape[2]
    num = -(-(max_disparity + 1) // 16) * 16
    matcher = cv2.StereoSGBM_create(
        minDisparity=min_disparity, numDisparities=num, blockSize=block_size,
        P1=8 * cn * block_size ** 2, P2=32 * cn * block_size ** 2,
        disp12MaxDiff=lr_tolerance, uniquenessRatio=uniqueness,
        speckleWindowSize=speckle_window, speckleRange=speckle_range,
        mode=cv2.STEREO_SGBM_MODE_SGBM)
    raw = matcher.compute(_squeeze(left), _squeeze(right))
    disp = raw.astype(np.float32) / 16.0
    bad = (raw < min_disparity * 16) | (disp > min_disparity + max_disparity) | ~lmask
    disp[bad] = np.nan
    _reject_invalid_partners(disp, rmask)
    return disp


def _reject_invalid_partners(disp: np.ndarray, rmask: np.ndarray,
                             largest: float | None = None) -> None:
    """NaN where the matched right pixel ``x - d`` (nearest pixel) is outside the right image
    or its validity mask (in place). ``largest``: no disparity exceeds it (None: unknown)."""
    H, W = disp.shape
    if rmask.all():  # only the left edge can be crossed (d >= 0); NaN compares False
        # x - d < -1/2 needs x < d: only the columns left of the largest disparity
        band = disp if largest is None else disp[:, :max(0, min(W, int(np.ceil(largest))))]
        with np.errstate(invalid="ignore"):
            band[np.rint(np.arange(band.shape[1], dtype=np.float32) - band) < 0] = np.nan
        return
    # x - d in float64 (exact), rounded; NaN stays NaN and compares False
    xr = np.subtract(np.arange(W, dtype=np.float64), disp)
    np.rint(xr, out=xr)
    runs = _single_runs(rmask)
    with np.errstate(invalid="ignore"):
        if runs is not None:  # a rectification's mask: one run [a, b) of valid pixels per row
            # float64 bounds: compared with int columns, numpy would convert every pixel's
            # float to float64 on the way; converting the H bounds once is cheaper
            a, b = (r.astype(np.float64) for r in runs)
            ok = xr >= a
            ok &= xr < b
        else:
            ok = xr >= 0
            ok &= xr < W
            np.copyto(xr, 0, where=~ok)
            at = xr.astype(np.intp)
            at += np.arange(0, H * W, W, dtype=np.intp)[:, None]  # flat index of the partner
            ok &= rmask.ravel().take(at)
    bad = np.isfinite(disp)
    bad &= ~ok
    disp[bad] = np.nan


def _single_runs(mask: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """``(a, b)``, (H, 1) int columns, when each row's True pixels are the one run
    ``a <= x < b`` (``a = W, b = 0`` on an empty row); None if some row has more runs."""
    H, W = mask.shape
    count = np.count_nonzero(mask, axis=1)
    a = np.argmax(mask, axis=1)
    b = W - np.argmax(mask[:, ::-1], axis=1)
    if not np.all((count == b - a) | (count == 0)):
        return None
    return np.where(count > 0, a, W)[:, None], np.where(count > 0, b, 0)[:, None]


def _squeeze(img: np.ndarray) -> np.ndarray:
    return img[:, :, 0] if img.shape[2] == 1 else img


def _grey(img: np.ndarray) -> np.ndarray:
    """(H, W) uint8 grey image of an (H, W, C) image (OpenCV BGR2GRAY weights)."""
    if img.shape[2] == 1:
        return np.ascontiguousarray(img[:, :, 0])
    return cv2.cvtColor(img, cv2.COLOR_BGR2GRAY)


def _check_options(**choices: str) -> None:
    allowed = {"color": COLOR_MODES, "subpixel": SUBPIXEL_MODES, "search": SEARCH_MODES,
               "occlusions": OCCLUSION_MODES, "postprocess": POSTPROCESS_MODES}
    for name, value in choices.items():
        if value not in allowed[name]:
            raise StereoError(f"{name}={value!r} is not one of {', '.join(allowed[name])}")


def _prepare(left, right, max_disparity, min_disparity, left_mask, right_mask):
    """Validate inputs; returns (H, W, C) uint8 images and (H, W) bool masks."""
    images = []
    for name, img in (("left", left), ("right", right)):
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
        images.append(np.ascontiguousarray(img))
    left, right = images
    if left.shape != right.shape:
        raise StereoError(f"image sizes differ: left {left.shape[1]}x{left.shape[0]}x"
                          f"{left.shape[2]}, right {right.shape[1]}x{right.shape[0]}x"
                          f"{right.shape[2]}")
    H, W = left.shape[:2]
    _check_range(max_disparity, min_disparity, W)
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


def _check_exact_width(width: int, channels: int, occ: int) -> None:
    limit = max_exact_width(channels, occ)
    if width > limit:
        raise StereoError(f"image width {width} exceeds {limit}, the widest row whose scanline "
                          f"costs stay exact ({channels} channel(s) summed, occlusion penalty "
                          f"{occ / 2 / channels:g}); crop or downscale the pair")


def _check_range(max_disparity, min_disparity, width: int) -> None:
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
