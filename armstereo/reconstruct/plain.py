"""Plain surfaces: a textureless region between textured pixels that agree gets their surface.

On a plain table top or wall the programme has no evidence of its own: its answers there are
guesses, and :func:`.rejection.unsupported` removes those its textured surroundings do not
confirm. What remains is often a hole in a surface whose boundaries say exactly where it is.
:func:`fill_plain` fills it: along a row (then along a column) a run of flat pixels bounded on
both sides by textured pixels whose disparities agree (within ``tolerance + slope * gap``)
takes the straight line between them on the pixels without an answer. In rectified images the
disparity of a plane is affine in the pixel coordinates, so a plane's hole is filled exactly.

Two pixels of a foreground at the same depth with a plain background between them agree too;
so a run is filled only when the programme itself supports the anchors' surface there: at
least ``support`` of the run's pixels had an answer within the anchors' range before the flat
pixels were tested. A background the programme saw elsewhere stays empty.
"""

from __future__ import annotations

import cv2
import numpy as np

from armstereo.reconstruct.birchfield.refine import row_rejects
from armstereo.reconstruct.strips import each_strip, row_strips

_NO_KIND = np.empty((0, 0), np.uint8)  # row_rejects' pixel kinds: not read by its fill mode
# row_rejects' flags test, use_along, apply, hidden, fill
_FILL_MODE = (np.bool_(False), np.bool_(False), np.bool_(False), np.bool_(False), np.bool_(True))


def fill_plain(disp: np.ndarray, before: np.ndarray, flat: np.ndarray, *, tolerance: float,
               slope: float, support: float, pool=None,
               strips: list[tuple[int, int]] | None = None) -> None:
    """Fill, in place, the NaN pixels of plain runs in the (H, W) float32 ``disp``: along the
    rows, then along the columns of the result (see the module doc). ``before``: the map
    before the flat pixels were tested (float32, NaN = no answer); ``flat``: (H, W) bool;
    ``tolerance`` (disparity pixels), ``slope`` (disparity per pixel) and ``support`` (share
    of a run, 0..1). Strips of rows (and as many of columns) run side by side on ``pool``."""
    H, W = disp.shape
    strips = strips or [(0, H)]
    # float32 values, as float64: the kernel's test is in float64, its range in float32
    args = (np.float64(np.float32(tolerance)), np.float64(np.float32(slope)), np.float64(support))
    each_strip(pool, strips, _fill_strip, disp, before, flat, args)
    each_strip(pool, row_strips(W, len(strips)), _fill_columns, disp, before, flat, args)


def _fill_strip(first: int, stop: int, disp, before, flat, args) -> None:
    fill_runs(disp, before, flat, *args, first, stop)


def fill_runs(disp: np.ndarray, before: np.ndarray, flat: np.ndarray, tolerance: np.float64,
              slope: np.float64, support: np.float64, first: int, stop: int) -> None:
    """Rows ``first .. stop - 1`` of :func:`fill_plain` along the rows (in place): the fill
    mode of :func:`.birchfield.refine.row_rejects`, which the rejections before it compile
    anyway (a kernel of its own cost ~0.6 s of first-run compile)."""
    row_rejects(disp, _NO_KIND, flat, flat, before, tolerance, slope, np.int64(0),
                np.float64(0.0), support, *_FILL_MODE, np.int64(first), np.int64(stop), flat)


def _fill_columns(first: int, stop: int, disp, before, flat, args) -> None:
    """Columns ``first .. stop - 1``: the row kernel on transposed copies (OpenCV's
    transpose: several times faster than numpy's copy of a transposed view)."""
    cols = slice(first, stop)
    d = cv2.transpose(disp[:, cols])
    b = cv2.transpose(before[:, cols])
    f = cv2.transpose(flat[:, cols].view(np.uint8)).view(np.bool_)
    fill_runs(d, b, f, *args, 0, stop - first)
    disp[:, cols] = cv2.transpose(d)
