"""Speckle removal, as SGBM does: NaN on small regions of similar disparity.

A region is a 4-connected set of answered pixels whose neighbours differ by at most
``max_diff``; one of at most ``size`` pixels is removed (OpenCV's ``filterSpeckles``, on a
1/16-pixel int16 copy of the map). ``filterSpeckles`` runs on one thread; on strips of rows
side by side it gives the same map as on the whole image, at the price of one extra band of
rows around each cut:

- what a strip's filter keeps, the whole image's keeps too: a region is at least as large
  as its part within the strip;
- a region the strip's filter removed and that does not cross a cut is the whole region,
  rightly removed;
- one that crosses a cut has at most ``size`` pixels, so it lies within ``size`` rows of the
  cut. The band of ``size`` rows each side of the cut, filtered on its own, keeps it if its
  region within the band is larger than ``size`` (then the whole region is too), and
  otherwise has seen all of it: a region crossing the cut and reaching the band's edge
  would span ``size + 1`` rows.

So a pixel is removed when its strip's filter and every band around it remove it.
"""

from __future__ import annotations

import cv2
import numpy as np

from armstereo.reconstruct.strips import each_strip

BAND_SHARE = 0.5  # the bands' rows at most this share of the image's: fewer strips then


def remove_speckles(disp: np.ndarray, size: int, max_diff: float, *, pool=None,
                    threads: int = 1) -> None:
    """NaN (in place) on the regions of at most ``size`` pixels of the (H, W) float32
    ``disp`` whose neighbours differ by at most ``max_diff`` pixels. With a ``pool`` and
    ``threads`` > 1, on strips of rows side by side (module doc) when the image is tall
    enough for it to pay; the same map either way."""
    runs = _runs(disp.shape[0], size, threads if pool is not None else 1)
    codes = np.empty(disp.shape, np.int16)
    bands = each_strip(pool, runs, _filter_rows, disp, codes, size, _code_diff(max_diff))
    for band in bands[1:]:
        first, kept = band
        np.copyto(codes[first:first + len(kept)], kept, where=kept >= 0)
    np.copyto(disp, np.float32(np.nan), where=codes < 0)


def _runs(height: int, size: int, threads: int) -> list[tuple[int, int]]:
    """Strips ``(first, stop)``, one per thread: every strip but the first also filters the
    band of ``2 size`` rows around its first row, so the first is that much taller. As many
    strips as the threads, or fewer where the bands would add more than BAND_SHARE of the
    image's rows (two strips from 4 ``size`` rows on): a single one on short images."""
    n = max(1, min(threads, 1 + int(BAND_SHARE * height) // (2 * max(1, size))))
    if n == 1:
        return [(0, height)]
    load = (height + 2 * size * (n - 1)) / n  # rows per thread
    rest = (height - load) / (n - 1)  # rows of each strip after the first
    cuts = [0] + [round(load + i * rest) for i in range(n - 1)] + [height]
    return list(zip(cuts[:-1], cuts[1:], strict=True))


def _filter_rows(first: int, stop: int, disp: np.ndarray, codes: np.ndarray, size: int,
                 diff: int) -> tuple[int, np.ndarray] | None:
    """Filter rows ``first .. stop - 1`` into ``codes`` (-1: NaN or removed) and, below the
    first strip, the band around row ``first`` on its own: returns ``(band_first, band)``
    (None for the first strip)."""
    rows = _codes(disp[first:stop], codes[first:stop])
    cv2.filterSpeckles(rows, -1, int(size), diff)  # in place: a view of whole rows
    if first == 0:
        return None
    a, b = max(0, first - size), min(disp.shape[0], first + size)
    band = _codes(disp[a:b])
    cv2.filterSpeckles(band, -1, int(size), diff)
    return a, band


def _codes(disp: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
    """The int16 1/16-pixel copy of ``disp`` the filter works on (-1: NaN), in ``out`` if
    given."""
    fixed = disp * np.float32(16)
    np.rint(fixed, out=fixed)
    np.copyto(fixed, -1, where=~np.isfinite(disp))  # cheaper than boolean indexing
    if out is None:
        return fixed.astype(np.int16)
    np.copyto(out, fixed, casting="unsafe")  # the cast astype makes, without a new array
    return out


def _code_diff(max_diff: float) -> int:
    """``max_diff`` pixels of disparity in :func:`_codes`' 1/16-pixel units."""
    return int(round(max_diff * 16))
