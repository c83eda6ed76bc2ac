"""Feature matching on a textured image and a copy moved by a known sub-pixel shift."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from armstereo.epipolar.errors import EpipolarError
from armstereo.epipolar.features import DETECTORS, harris_corners, match_features

SHIFT = np.array([23.4, -3.7])  # px, image 2 = image 1 moved right and up


def texture(seed: int = 0, size=(480, 640)) -> np.ndarray:
    """Band-limited random blobs (a few px wide, never per-pixel noise), BGR uint8."""
    rng = np.random.default_rng(seed)
    g = cv2.GaussianBlur(rng.normal(0, 1, size).astype(np.float32), (0, 0), 2.0)
    g = 255 / (1 + np.exp(-3 * g / g.std()))
    return cv2.cvtColor(g.astype(np.uint8), cv2.COLOR_GRAY2BGR)


@pytest.fixture(scope="module")
def shifted_pair():
    im1 = texture()
    M = np.array([[1.0, 0.0, SHIFT[0]], [0.0, 1.0, SHIFT[1]]])
    im2 = cv2.warpAffine(im1, M, (im1.shape[1], im1.shape[0]), flags=cv2.INTER_CUBIC,
                         borderMode=cv2.BORDER_REFLECT)
    return im1, im2


@pytest.mark.parametrize("detector, tolerance", [("harris", 0.1), ("sift", 0.3),
                                                 ("orb", 1.0)])
def test_matches_follow_the_known_shift(shifted_pair, detector, tolerance):
    m = match_features(*shifted_pair, detector)
    assert len(m) > 100
    err = np.linalg.norm(m.x2 - m.x1 - SHIFT, axis=1)
    assert np.median(err) < tolerance
    assert np.mean(err < 2.0) > 0.95  # mutual-best + ratio tests leave few wrong matches
    assert m.detector == detector and m.keypoints[0] >= len(m)


def test_harris_corners_are_sub_pixel_and_clear_of_the_border(shifted_pair):
    pts = harris_corners(cv2.cvtColor(shifted_pair[0], cv2.COLOR_BGR2GRAY))
    assert len(pts) > 200
    assert np.any(np.abs(pts - np.round(pts)) > 0.05)  # refined off the pixel grid
    assert pts.min() >= 8 and pts[:, 0].max() <= 639 - 8 and pts[:, 1].max() <= 479 - 8


def test_the_search_window_bounds_the_displacement(shifted_pair):
    m = match_features(*shifted_pair, "harris", search_radius=(10.0, 10.0))
    assert np.all(np.abs(m.x2 - m.x1) <= 10.0)  # the true partner (23 px away) is outside
    assert len(m) < 50


def test_masks_restrict_where_features_are_found(shifted_pair):
    mask = np.zeros((480, 640), bool)
    mask[:, :320] = True
    m = match_features(*shifted_pair, "sift", mask1=mask)
    assert len(m) > 20 and m.x1[:, 0].max() < 320


def test_flat_images_give_no_matches():
    flat = np.full((120, 160), 128, np.uint8)
    for detector in DETECTORS:
        assert len(match_features(flat, flat, detector)) == 0


@pytest.mark.parametrize("kwargs, match", [
    (dict(detector="surf"), "unknown detector"),
    (dict(max_features=3), "max_features"),
    (dict(ratio=1.5), "ratio"),
    (dict(mask1=np.ones((10, 10), bool)), "mask1"),
])
def test_bad_options_raise(shifted_pair, kwargs, match):
    with pytest.raises(EpipolarError, match=match):
        match_features(*shifted_pair, **kwargs)


def test_bad_images_raise():
    with pytest.raises(EpipolarError, match="uint8"):
        match_features(np.zeros((10, 10), np.float32), np.zeros((10, 10), np.uint8))
