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

Defaults of :func:`birchfield`, measured with ``bench/stereo.py --variants`` (four Middlebury
pairs and two rendered scenes; bad-2 on non-occluded pixels averaged, "wrong" = answered
pixels off by more than 2 px; table in bench/results/stereo.md):

- the paper's ``occlusion_penalty=25``, ``match_reward=5``: 35 lowers the average bad-2
  (3.5 % against 3.7 %) but worsens four of the six pairs; 15, and rewards 3 or 8, are worse;
- ``color="gray"``: summing the channels (3.9 %) or taking their maximum (4.8 %) did not help
  on average and takes 1.6-2.5x the time;
- ``postprocess=True``: without it 4.9 %;
- ``subpixel="gradient"``: 3.7 % against 3.8 % without and 3.9 % with the parabola, and the
  smallest median error (0.13 px against 0.25 px without), for 15-35 % more time;
- ``occlusions="nan"``: the paper's background fill scores better on bad-2 (3.1 %), which
  counts a missing answer as wrong, but answers wrongly more often (4.1 % of its answers,
  against 3.7 %); for point clouds a hole is cheaper than a false point;
- ``lr_check=False``: it removes more false answers (3.3 %) but also good ones (bad-2 4.8 %)
  and takes 1.6-2.3x the time; worth it where outliers matter more than coverage;
- ``search="exact"``: the reference code's pruned search is about as accurate, 18x slower.
"""

from __future__ import annotations

import logging

import cv2
import numpy as np

from armstereo.errors import StereoError
from armstereo.reconstruct.birchfield import dp_pruned as _dp
from armstereo.reconstruct.birchfield.dp_exact import max_exact_width
from armstereo.reconstruct.birchfield.matcher import DP_EXACT, DP_PRUNED, match_image
from armstereo.reconstruct.birchfield.postprocess import postprocess as _postprocess
from armstereo.reconstruct.birchfield.refine import (
    left_right_mismatch,
    occluded_by_nearer,
    refine_gradient,
    refine_parabola,
)

log = logging.getLogger(__name__)

METHODS = ("birchfield", "sgbm")
COLOR_MODES = ("gray", "sum", "max")
SUBPIXEL_MODES = ("none", "parabola", "gradient")
SEARCH_MODES = ("exact", "pruned")
OCCLUSION_MODES = ("nan", "fill")

# gradient refinement passes: averaged bad-2 3.79 % with 1, 3.72 % with 2, 3.68 % with 3
SUBPIXEL_ITERATIONS = 2
SUBPIXEL_MAX_SHIFT = 1.0


def birchfield(left: np.ndarray, right: np.ndarray, max_disparity: int, *,
               min_disparity: int = 0, occlusion_penalty: float = 25, match_reward: float = 5,
               color: str = "gray", postprocess: bool = True, occlusions: str = "nan",
               lr_check: bool = False, subpixel: str = "gradient", subpixel_radius: int = 5,
               search: str = "exact", left_mask: np.ndarray | None = None,
               right_mask: np.ndarray | None = None, threads: int | None = None) -> np.ndarray:
    """Birchfield-Tomasi pixel-to-pixel stereo (ICCV'98) with the paper's postprocessing.

    The algorithm: the sampling-insensitive symmetric dissimilarity, one dynamic programme per
    scanline over match sequences (an occlusion costs ``occlusion_penalty`` once, each match
    earns ``match_reward``, occlusions only next to intensity variation; grey-level units), then
    the paper's propagation across scanlines and mode filters (``postprocess``). Options beyond
    the paper:

    - ``search``: ``"exact"`` solves each scanline's programme exactly in O(width x
      disparities) with running minima; ``"pruned"`` is the reference code's pruned search (a
      heuristic, O(width x disparities^2) in flat regions): about the same accuracy, 18x
      slower.
    - ``color``: ``"gray"`` matches the BGR2GRAY image (the paper's setting); ``"sum"``/
      ``"max"`` combine per-channel dissimilarities (the sum is scaled back to grey units).
    - ``occlusions``: ``"nan"`` leaves NaN on left pixels the final map itself shows hidden by
      a nearer pixel (more than one pixel behind, so slanted surfaces keep their pixels);
      ``"fill"`` keeps the paper's background fill there.
    - ``lr_check``: also match right-to-left (mirrored pair) and reject disparities that differ
      by more than one pixel. Matching takes twice as long.
    - ``subpixel``: ``"gradient"`` (iterated 1-D Lucas-Kanade over a window of the same
      surface), ``"parabola"`` (parabola through windowed SSD at d-1, d, d+1) or ``"none"``;
      the window is ``2 * subpixel_radius + 1`` pixels square.
    - ``threads``: rows are matched on this many threads (default ``numba.get_num_threads()``).

    Defaults were chosen by measurement: see "Defaults" in the module doc.

    Untextured regions take their disparity from their edges and from propagation; a
    completely flat pair gives ``min_disparity`` everywhere, as in the paper. Left pixels whose
    partner would lie left of the right image (the strip ``x < d``) are NaN.

    Raises StereoError for unusable input (sizes, dtype, disparity range, masks, options).
    """
    _check_options(color=color, subpixel=subpixel, search=search, occlusions=occlusions)
    left, right, lmask, rmask = _prepare(left, right, max_disparity, min_disparity, left_mask,
                                         right_mask)
    if threads is not None and threads < 1:
        raise StereoError(f"threads must be >= 1, got {threads}")
    if occlusion_penalty < 0 or match_reward < 0 or subpixel_radius < 0:
        raise StereoError(f"occlusion_penalty ({occlusion_penalty}), match_reward "
                          f"({match_reward}) and subpixel_radius ({subpixel_radius}) must be >= 0")
    gl, gr = _grey(left), _grey(right)
    ml, mr = (gl[:, :, None], gr[:, :, None]) if color == "gray" else (left, right)
    units = 2 * (ml.shape[2] if color == "sum" else 1)  # doubled units, summed channels
    occ = int(round(occlusion_penalty * units))
    if search == "exact":
        _check_exact_width(left.shape[1], ml.shape[2] if color == "sum" else 1, occ)
    params = dict(dmin=min_disparity, nd=max_disparity + 1,
                  occ=occ, rew=int(round(match_reward * units)),
                  combine_max=color == "max", mode=DP_EXACT if search == "exact" else DP_PRUNED,
                  threads=threads, postprocess=postprocess)
    idx = _match(ml, mr, lmask, rmask, **params)
    reject = idx < 0
    if occlusions == "nan":
        reject |= occluded_by_nearer(idx, 1)
    if lr_check:
        idx_r = _match(mr[:, ::-1], ml[:, ::-1], rmask[:, ::-1], lmask[:, ::-1], **params)
        # mirrored, swapped pair: its "left" is the mirrored right image
        idx_r = np.ascontiguousarray(idx_r[:, ::-1])
        reject |= left_right_mismatch(idx, idx_r, min_disparity, 1)
    disp = (idx + min_disparity).astype(np.float32)
    disp[reject] = np.nan
    if subpixel == "gradient":
        disp = refine_gradient(gl.astype(np.float32), gr.astype(np.float32), disp,
                               subpixel_radius, SUBPIXEL_ITERATIONS, SUBPIXEL_MAX_SHIFT)
    elif subpixel == "parabola":
        disp = refine_parabola(gl.astype(np.float32), gr.astype(np.float32), disp,
                               subpixel_radius)
    return disp


def _match(left, right, lmask, rmask, *, dmin, nd, occ, rew, combine_max, mode, threads,
           postprocess):
    """Scanline matching (+ postprocessing) -> int32 window indices, -1 = no match."""
    lm = np.ascontiguousarray(left)
    rm = np.ascontiguousarray(right)
    idx, state = match_image(lm, rm, np.ascontiguousarray(lmask), np.ascontiguousarray(rmask),
                             dmin, nd, occ, rew, combine_max=combine_max, mode=mode,
                             threads=threads)
    # The dense map (border strip and occlusions filled as in the reference code) feeds the
    # postprocessing; pixels without a possible partner are removed afterwards.
    if postprocess:
        idx = _postprocess(idx, lm, nd)
    idx[state >= _dp.BORDER] = -1
    return idx


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


def _reject_invalid_partners(disp: np.ndarray, rmask: np.ndarray) -> None:
    """NaN where the matched right pixel is outside the right validity mask (in place)."""
    if rmask.all():
        return
    H, W = disp.shape
    ys, xs = np.nonzero(np.isfinite(disp))
    xr = np.rint(xs - disp[ys, xs]).astype(np.int64)
    off = (xr < 0) | (xr >= W)
    off[~off] = ~rmask[ys[~off], xr[~off]]
    disp[ys[off], xs[off]] = np.nan


def _squeeze(img: np.ndarray) -> np.ndarray:
    return img[:, :, 0] if img.shape[2] == 1 else img


def _grey(img: np.ndarray) -> np.ndarray:
    """(H, W) uint8 grey image of an (H, W, C) image (OpenCV BGR2GRAY weights)."""
    if img.shape[2] == 1:
        return np.ascontiguousarray(img[:, :, 0])
    return cv2.cvtColor(img, cv2.COLOR_BGR2GRAY)


def _check_options(**choices: str) -> None:
    allowed = {"color": COLOR_MODES, "subpixel": SUBPIXEL_MODES, "search": SEARCH_MODES,
               "occlusions": OCCLUSION_MODES}
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
