"""birchfield(photo_check=...): matches whose two views do not look alike are rejected.

The case it is for: a left pixel that shows background the foreground hides from the right
camera (the half-occluded strip beside a tall object) has no true partner; whatever disparity
it gets (the foreground's when the matcher fattens it, the background's when the paper's fill
gives it one) pairs it with a right pixel that shows something else.
"""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from armstereo.errors import StereoError
from armstereo.reconstruct import rejection
from armstereo.reconstruct.stereo import CLEAN_PHOTO_CHECK, birchfield
from tests.support.images import box_pair as textured_box_pair
from tests.support.images import texture

NOISE = 1.0  # grey levels per view, as the mock camera's ideal profile


def _noisy(img: np.ndarray, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return np.clip(np.rint(img + rng.normal(0, NOISE, img.shape)), 0, 255).astype(np.uint8)


def box_pair(d_bg=3, d_fg=11, box=(50, 100, 20, 60), shape=(80, 140), seed=1):
    """:func:`tests.support.images.box_pair` with camera noise; left pixels ``x0 - (d_fg -
    d_bg) .. x0 - 1`` of the box's rows show background the box hides from the right camera."""
    left, right = textured_box_pair(d_bg, d_fg, box, shape=shape, seed=seed)
    return _noisy(left, seed + 1), _noisy(right, seed + 2)


def test_the_strip_filled_with_the_background_is_rejected_and_the_rest_kept():
    d_bg, d_fg, (x0, x1, y0, y1) = 3, 11, (50, 100, 20, 60)
    left, right = box_pair(d_bg, d_fg, (x0, x1, y0, y1))
    opts = dict(occlusions="fill", subpixel="none")  # the paper's fill answers in the strip
    filled = birchfield(left, right, 15, **opts)
    checked = birchfield(left, right, 15, photo_check=CLEAN_PHOTO_CHECK, **opts)
    rows = slice(y0 + 3, y1 - 3)
    strip = slice(x0 - (d_fg - d_bg) + 1, x0 - 1)
    assert np.isfinite(filled[rows, strip]).all()  # without the check: answers there
    assert np.isnan(checked[rows, strip]).mean() > 0.9
    # the box and the background away from the strip keep their answers
    assert np.isfinite(checked[rows, x0 + 2:x1 - 2]).mean() > 0.99
    assert np.isfinite(checked[rows, x1 + 2:]).mean() > 0.99
    assert np.isfinite(checked[:y0 - 2, d_bg + 2:]).mean() > 0.99


def test_a_fattened_foreground_is_rejected_on_the_strip_only():
    d_bg, d_fg, (x0, x1, y0, y1) = 3, 11, (50, 100, 20, 60)
    left, right = box_pair(d_bg, d_fg, (x0, x1, y0, y1), seed=5)
    width = d_fg - d_bg
    disp = np.full(left.shape, np.float32(d_bg))
    disp[y0:y1, x0 - width:x1] = d_fg  # the box's disparity carried across the strip
    bad = rejection.photo_inconsistent(left, right, disp, CLEAN_PHOTO_CHECK)
    rows = slice(y0 + 2, y1 - 2)
    assert bad[rows, x0 - width + 1:x0 - 1].mean() > 0.9
    assert bad[rows, x0 + 2:x1 - 2].mean() < 0.01
    assert bad[:y0 - 2, d_bg + 2:].mean() < 0.01


@pytest.mark.parametrize("shift", [2.0, 4.3, 7.5])
def test_a_textured_plane_keeps_its_answers(shift):
    H, W = 60, 140
    tex = texture((H, W + 20), 9, blur=2.0).astype(np.float32)
    xs, ys = np.meshgrid(np.arange(W, dtype=np.float32) + np.float32(shift),
                         np.arange(H, dtype=np.float32))
    right = cv2.remap(tex, xs, ys, cv2.INTER_CUBIC)
    left, right = _noisy(tex[:, :W], 10), _noisy(right, 11)
    dense = dict(texture_threshold=0.0)  # an answer on every pixel of the plane
    plain = birchfield(left, right, 15, **dense)
    checked = birchfield(left, right, 15, photo_check=CLEAN_PHOTO_CHECK, **dense)
    answered = np.isfinite(plain)
    assert answered[:, 10:].mean() > 0.99
    assert np.isfinite(checked[answered]).mean() > 0.995
    np.testing.assert_array_equal(checked[np.isfinite(checked)],
                                  plain[np.isfinite(checked)])


def test_off_by_default_and_a_negative_threshold_is_refused():
    left, right = box_pair(seed=7)
    np.testing.assert_array_equal(birchfield(left, right, 15),
                                  birchfield(left, right, 15, photo_check=0.0))
    with pytest.raises(StereoError, match="photo_check"):
        birchfield(left, right, 15, photo_check=-1.0)
