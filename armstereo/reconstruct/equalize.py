"""Brightness equalisation: the right view made as bright as the left before they are compared.

The two views of an arm's pair are taken at different times from different places: exposure,
gain, the response curve, vignetting and the light on the scene differ between them, and the
paper's dissimilarity compares intensities. :func:`equalize` estimates that difference from the
pair itself and removes it from the right image:

1. a quick first pass matches the pair at half size, on every :data:`ROW_STEP`-th row, with a
   cost that ignores brightness (the locally normalised images, :mod:`.normalize`);
2. the matched pixels give samples ``(L(x), R(x - d))`` of the two images' intensities at the
   same scene point (both blurred a little, so a sub-pixel misregistration does not count);
3. the model ``L = G(x_r, y) * R ** gamma`` is fitted to them robustly (in logarithms: one
   ``gamma`` for the image, the ratio of the two images' spreads about their cells' means,
   one gain per :data:`CELL` x :data:`CELL` cell of the right image,
   samples more than :data:`TRIM` from the fit left out, three rounds), the cells' gains
   smoothed and interpolated into a field;
4. the right image becomes ``G * R ** gamma``, unless that changes nine in ten of the
   samples by less than :data:`NEGLIGIBLE` (the pair already agrees) or fits them hardly
   better than no change (:data:`BETTER`: the first pass found too few true matches); then
   the pair is left as it is.

A gain, a gamma, vignetting and light that changes slowly across the image are all of this
form; on a pair without such a difference the fit is the identity (gamma 1, gains 1) to within
its noise. What the model cannot express (a highlight that moves with the view, clipping) stays.
The intensities themselves are then matched, so the shading of plain, smooth surfaces still
guides the programme (a cost that normalises every window away loses it: bench/results/
radiometric.md).
"""

from __future__ import annotations

from collections.abc import Callable

import cv2
import numpy as np

ROW_STEP = 4  # rows of the half-size pair the first pass matches: 1 in 4
CELL = 16  # pixels: side of the right image's cells that each get a gain
TRIM = 0.1  # log units: samples further than this from the fit are left out
SAMPLE_BLUR = 2.0  # full-size px: Gaussian on both images before sampling
DARK, BRIGHT = 12.0, 243.0  # grey levels: samples outside (noise, clipping) are not used
MIN_SAMPLES = 1000  # fewer matched samples: the pair is left as it is
NEGLIGIBLE = 1.0  # grey levels: a correction smaller on 90 % of the samples is not applied
DECIDE_STEP = 4  # one sample in this many decides whether the fit is applied
BETTER = 0.7  # the fit's median residual must be below this share of the identity's
PRIOR = 0.5  # samples: a cell's gain is pulled towards the image's as if it had this many more


def equalize(grey_l: np.ndarray, grey_r: np.ndarray, lmask: np.ndarray, rmask: np.ndarray,
             min_disparity: int, max_disparity: int,
             first_pass: Callable[..., np.ndarray]) -> np.ndarray:
    """The (H, W) uint8 right grey image with the left image's brightness (module doc).

    ``grey_l``/``grey_r``: (H, W) uint8; ``lmask``/``rmask``: (H, W) bool valid pixels; the
    searched window as the matcher's. ``first_pass(left, right, max_disparity,
    min_disparity=, left_mask=, right_mask=)`` matches the half-size rows (a brightness-blind
    matcher); a pair too small for it, or with too few matched samples, is returned as it is.
    """
    H, W = grey_l.shape
    h, w = H // 2, W // 2
    lo = min_disparity // 2
    n = -(-(min_disparity + max_disparity) // 2) - lo
    if h < 2 * ROW_STEP or n < 1 or lo + n >= w:
        return grey_r
    # an even-sized crop: OpenCV's area resize by exactly 2 is its fast path (an odd size
    # costs about a millisecond more)
    half = [cv2.resize(g[:2 * h, :2 * w], (w, h), interpolation=cv2.INTER_AREA)
            for g in (grey_l, grey_r)]
    if lmask.all() and rmask.all():  # no rectification fill: nothing to resize or test
        rows = np.ones((-(-h // ROW_STEP), w), np.bool_)
        masks, row_masks = None, (rows, rows)
    else:
        masks = [cv2.resize(m[:2 * h, :2 * w].view(np.uint8), (w, h),
                            interpolation=cv2.INTER_NEAREST) > 0 for m in (lmask, rmask)]
        row_masks = tuple(m[::ROW_STEP] for m in masks)
    d = first_pass(half[0][::ROW_STEP], half[1][::ROW_STEP], n, min_disparity=lo,
                   left_mask=row_masks[0], right_mask=row_masks[1])
    samples = _samples(half, masks, d)
    if samples is None:
        return grey_r
    gamma, gain = _fit(*samples, h, w)
    if not _worth_applying(samples, gamma, gain):
        return grey_r
    # R ** gamma by a table of the 256 grey levels, times the gain field at full size
    curve = np.power(np.maximum(np.arange(256, dtype=np.float32), np.float32(0.5)),
                     np.float32(gamma))
    field = cv2.resize(gain, (W, H), interpolation=cv2.INTER_LINEAR)
    # OpenCV's product to uint8 rounds and saturates: np.clip(np.rint(.)) in one pass
    return cv2.multiply(curve[grey_r], field, dtype=cv2.CV_8U)


def _worth_applying(samples, gamma: float, gain: np.ndarray) -> bool:
    """Whether the fit should change the right image: it must change nine in ten samples by
    NEGLIGIBLE grey levels or more (else the pair already agrees), and it must explain the
    samples clearly better than leaving the image as it is (median residual below BETTER
    times the identity's; else the first pass's matches were too poor to fit)."""
    y, xr, log_l, log_r = (v[::DECIDE_STEP] for v in samples)  # plenty to decide on
    b = np.exp(log_r)
    corrected = gain[y, xr] * b ** np.float32(gamma)
    if _percentile_below(np.abs(corrected - b), 90, NEGLIGIBLE):
        return False
    fitted = _median(np.abs(log_l - np.log(corrected)))
    return bool(fitted < BETTER * _median(np.abs(log_l - log_r)))


def _median(v: np.ndarray):
    """``np.median`` of the 1-D float array ``v``: the same partition and mean of the middle
    one or two values, without its generic set-up (tens of microseconds a call here)."""
    n = v.shape[0]
    if n == 0:
        return np.median(v)
    half = n // 2
    part = np.partition(v, [half - 1, half, -1] if n % 2 == 0 else [half, -1])
    if np.isnan(part[-1]):  # NaN sorts last: np.median's answer is NaN
        return np.median(v)
    return np.mean(part[half - 1:half + 1] if n % 2 == 0 else part[half:half + 1], axis=0)


def _percentile_below(v: np.ndarray, q: float, limit: float) -> bool:
    """Whether ``np.percentile(v, q) < limit`` (linear interpolation), from the two sorted
    values it interpolates between: np.percentile itself only where they straddle
    ``limit`` closely enough for its rounding to matter."""
    n = v.shape[0]
    if n < 2:
        return bool(np.percentile(v, q) < limit)
    lo = int(np.floor((n - 1) * (q / 100.0)))
    hi = min(lo + 1, n - 1)
    part = np.partition(v, [lo, hi, -1])
    a, b = float(part[lo]), float(part[hi])
    margin = 1e-5 * max(1.0, abs(limit))  # far more than a float32 interpolation's rounding
    if not np.isnan(part[-1]) and b < limit - margin:
        return True
    if not np.isnan(part[-1]) and a >= limit + margin:
        return False
    return bool(np.percentile(v, q) < limit)


def _samples(half, masks, d):
    """``(y, x_r, log L, log R)`` (half-size pixels) of the matched, valid, well-exposed
    pixels of the first pass's rows; None if fewer than MIN_SAMPLES. ``masks``: the
    half-size validity masks (None: every pixel valid)."""
    w = half[0].shape[1]
    blur = [cv2.GaussianBlur(g, (0, 0), SAMPLE_BLUR / 2)[::ROW_STEP].astype(np.float32)
            for g in half]
    iy, xs = np.nonzero(np.isfinite(d))
    xr = np.rint(xs - d[iy, xs]).astype(np.int64)
    ok = (xr >= 0) & (xr < w)
    iy, xs, xr = iy[ok], xs[ok], xr[ok]
    a, b = blur[0][iy, xs], blur[1][iy, xr]
    ok = (a > DARK) & (b > DARK) & (a < BRIGHT) & (b < BRIGHT)
    if masks is not None:
        ok &= masks[0][::ROW_STEP][iy, xs] & masks[1][::ROW_STEP][iy, xr]
    if np.count_nonzero(ok) < MIN_SAMPLES:
        return None
    return iy[ok] * ROW_STEP, xr[ok], np.log(a[ok]), np.log(b[ok])


def _fit(y, xr, log_l, log_r, h: int, w: int) -> tuple[float, np.ndarray]:
    """``gamma`` and the (h, w) float32 gain field ``G`` of ``log L = log G + gamma log R``
    (half-size pixels): gamma from the samples' deviations from their cells' means, one
    offset per cell, three rounds without the samples further than TRIM from the fit."""
    side = CELL // 2
    gh, gw = -(-h // side), -(-w // side)
    cell = (y // side) * gw + xr // side
    keep = None  # the first round takes every sample
    gamma = 1.0
    for _ in range(3):
        # the kept samples picked once per round: a cell's sums, and the deviations from
        # its means, are those of the whole arrays' kept entries (same values, same order)
        ck, lk, rk = (cell, log_l, log_r) if keep is None else (cell[keep], log_l[keep],
                                                                 log_r[keep])
        count = np.bincount(ck, minlength=gh * gw).astype(np.float64)
        safe = np.maximum(count, 1)
        mean_l = np.bincount(ck, lk, minlength=gh * gw) / safe
        mean_r = np.bincount(ck, rk, minlength=gh * gw) / safe
        dl, dr = lk - mean_l[ck], rk - mean_r[ck]
        # the ratio of the spreads, not a regression of one on the other: mismatched samples
        # would pull a regression's slope towards 0 (and the gains with it); sums of squares,
        # not np.dot: BLAS threads cost milliseconds on a busy machine
        spread_l, spread_r = float(np.sum(dl * dl)), float(np.sum(dr * dr))
        if spread_l > 0 and spread_r > 0:
            gamma = (spread_l / spread_r) ** 0.5
        offset = mean_l - gamma * mean_r
        keep = np.abs(log_l - gamma * log_r - offset[cell]) < TRIM
        if np.count_nonzero(keep) < MIN_SAMPLES:
            return 1.0, np.ones((h, w), np.float32)
    # a cell with few samples keeps nearly the image's gain (its own mean is mostly noise);
    # cells without samples take their neighbours' gains (normalised convolution)
    overall = float(np.sum(offset * count) / max(np.sum(count), 1.0))
    offset = (offset * count + PRIOR * overall) / (count + PRIOR)
    weight = count + PRIOR
    num = cv2.GaussianBlur((offset * weight).reshape(gh, gw).astype(np.float32), (0, 0), 1.0)
    den = cv2.GaussianBlur(weight.reshape(gh, gw).astype(np.float32), (0, 0), 1.0)
    gain = np.exp(num / np.maximum(den, np.float32(1e-6)))
    gain = cv2.resize(gain, (gw * side, gh * side), interpolation=cv2.INTER_LINEAR)
    return gamma, np.ascontiguousarray(gain[:h, :w])
