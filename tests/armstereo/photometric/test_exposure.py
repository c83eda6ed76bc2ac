"""The pair's exposure and white-balance gain, estimated from its two views."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from armstereo.photometric.exposure import (
    GAIN_TOLERANCE,
    apply_gains,
    dominant_shift,
    pair_gains,
)


def textured_pair(shift: int = 23, seed: int = 0):
    """A rectified pair: textured blobs on a plain, slowly shaded surface; the right view is
    the left shifted by ``shift`` px (x_right = x_left - d), with its own noise."""
    rng = np.random.default_rng(seed)
    h, w = 240, 400
    base = cv2.GaussianBlur(rng.uniform(0, 1, (h, w + shift, 3)).astype(np.float32), (0, 0), 3)
    shade = np.linspace(0.8, 1.0, w + shift, dtype=np.float32)[None, :, None]
    scene = (90 + 600 * (base - base.mean())) * shade
    scene[:, : (w + shift) // 3] = 120 * shade[:, : (w + shift) // 3]  # a plain part
    left = scene[:, :w]
    right = scene[:, shift:]  # right[x - shift] = left[x]
    noise = rng.normal(0, 1.0, (2, h, w, 3)).astype(np.float32)
    to8 = lambda a: np.clip(np.rint(a), 0, 255).astype(np.uint8)  # noqa: E731
    return to8(left + noise[0]), to8(right + noise[1])


def test_the_dominant_shift_is_the_disparity():
    left, right = textured_pair(shift=23)
    assert dominant_shift(left, right, 60) == 23


@pytest.mark.parametrize("gains", [(1.06, 0.97, 1.02), (0.9, 0.9, 0.9)])
def test_a_known_gain_is_recovered_to_a_few_tenths_of_a_percent(gains):
    left, right = textured_pair()
    darker = apply_gains(right, np.asarray(gains))
    est = pair_gains(left, darker, 60)
    np.testing.assert_allclose(est, 1.0 / np.asarray(gains), rtol=0.004)


def test_equal_exposures_give_gains_within_tolerance_and_leave_the_image_alone():
    left, right = textured_pair()
    est = pair_gains(left, right, 60)
    assert np.all(np.abs(est - 1.0) <= GAIN_TOLERANCE)
    assert apply_gains(right, est) is right


def test_too_little_overlap_tells_no_gain():
    left, right = textured_pair()
    mask = np.zeros(left.shape[:2], bool)
    mask[:5, :5] = True
    assert pair_gains(left, right, 60, left_mask=mask) is None


def test_grey_images_get_one_gain():
    left, right = textured_pair()
    grey = [cv2.cvtColor(v, cv2.COLOR_BGR2GRAY) for v in (left, right)]
    est = pair_gains(grey[0], apply_gains(grey[1], np.array([0.95])), 60)
    assert est.shape == (1,) and est[0] == pytest.approx(1 / 0.95, rel=0.004)
