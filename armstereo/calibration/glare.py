"""Board corners under a glare: found in the image, left out of the calibration.

A laminated board reflects the light in some views. The highlight adds a smooth bright patch
on top of the print; a chessboard corner inside it is still found, but the added brightness
gradient and the clipped white paper pull the sub-pixel corner by a tenth to a quarter of a
pixel (the mock cell's realistic board: 0.1-0.27 px against 0.03 px of noise), always towards
the same side of the spot. The refinement cannot tell that from geometry: on the realistic
cell it biased the hand-eye by 0.13 mm along the optical axis and the focal length by -0.02 %
on average over seeds (bench/results/calibration_prediction.md), and made the predicted error
too small for the worst cells.

The print's ink-to-paper ratio is one number for the whole board, whatever the lighting,
exposure or vignetting (both scale alike), while a glare *adds* light, which raises it. So for
every corner the four squares around it are sampled (their centres, placed from the
neighbouring corners, so lens distortion does not matter); the darker diagonal pair is ink, the
other paper, and a corner whose ratio stands more than :data:`GLARE_RATIO_EXCESS` above the
view's median is left out. On the mock cell that threshold leaves no corner of a view without
glare out, and the corners it keeps move by less than the noise. The median is the print's
ratio as long as the glare covers less than half of the view's corners (a laminate's highlight
is a spot); a view lit up all over is not recognised.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from armstereo.calibration.board import Board, Detection, _grey

# Ink/paper ratio above the view's median beyond which a corner is in a glare. Measured on the
# mock cell (seeds 0-1, the same views rendered with and without the laminate's glare): corners
# above 0.01 moved by 0.015-0.12 px, those below by what the noise moves them (0.01-0.03 px).
GLARE_RATIO_EXCESS = 0.01
_PATCH = 1  # half-size (px) of the square patch whose median samples a square's grey level


@dataclass(frozen=True)
class GlareScreen:
    """What the screen did to one view: corners found and corners left out."""

    found: int
    left_out: int

    def as_dict(self) -> dict:
        return {"found": self.found, "left_out": self.left_out}


def ink_paper_ratio(image: np.ndarray, det: Detection, board: Board) -> np.ndarray:
    """(N,) grey level of the darker diagonal pair of squares around each corner over that of
    the lighter pair (uint8 grey or BGR ``image``; NaN where a square centre is off the
    image)."""
    grey = _grey(image)
    P = det.image_points
    grid = np.rint(det.object_points[:, :2] / board.square_m).astype(int)
    index = {(int(a), int(b)): i for i, (a, b) in enumerate(grid)}
    levels = np.full((len(P), 4), np.nan)
    h, w = grey.shape
    for i, (a, b) in enumerate(grid):
        ex = _step(P, index, i, int(a), int(b), 1, 0)
        ey = _step(P, index, i, int(a), int(b), 0, 1)
        if ex is None or ey is None:
            continue
        for q, (sx, sy) in enumerate(((1, 1), (-1, 1), (-1, -1), (1, -1))):
            x, y = np.rint(P[i] + 0.5 * sx * ex + 0.5 * sy * ey).astype(int)
            if _PATCH <= x < w - _PATCH and _PATCH <= y < h - _PATCH:
                levels[i, q] = np.median(grey[y - _PATCH:y + _PATCH + 1,
                                              x - _PATCH:x + _PATCH + 1])
    pair_a = (levels[:, 0] + levels[:, 2]) / 2
    pair_b = (levels[:, 1] + levels[:, 3]) / 2
    ink, paper = np.minimum(pair_a, pair_b), np.maximum(pair_a, pair_b)
    with np.errstate(invalid="ignore", divide="ignore"):
        return ink / np.maximum(paper, 1.0)


def _step(P: np.ndarray, index: dict, i: int, a: int, b: int, da: int, db: int):
    """Image vector of one grid step (da, db) at corner i: to the next corner, else from the
    previous one; None when it has neither neighbour."""
    j = index.get((a + da, b + db))
    if j is not None:
        return P[j] - P[i]
    j = index.get((a - da, b - db))
    return None if j is None else P[i] - P[j]


def without_glare(image: np.ndarray, det: Detection | None,
                  board: Board) -> tuple[Detection | None, GlareScreen | None]:
    """``det`` without its corners under a glare (module doc), and what was left out (None
    for a view without a detection). At most half of the corners go (the median is the
    baseline), so every view keeps its board pose."""
    if det is None:
        return None, None
    ratio = ink_paper_ratio(image, det, board)
    if not np.any(np.isfinite(ratio)):
        return det, GlareScreen(len(det), 0)
    glared = ratio > np.nanmedian(ratio) + GLARE_RATIO_EXCESS  # NaN compares False: kept
    n_out = int(np.sum(glared))
    if n_out == 0:
        return det, GlareScreen(len(det), 0)
    keep = ~glared
    return (Detection(det.ids[keep], det.image_points[keep], det.object_points[keep]),
            GlareScreen(len(det), n_out))
