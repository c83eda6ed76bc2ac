"""Local normalisation: brightness-blind images, the same on a strip of rows as on the whole."""

from __future__ import annotations

import numpy as np

from armstereo.reconstruct.normalize import normalize
from tests.support.images import texture


def grey_texture(shape=(64, 80), seed=0) -> np.ndarray:
    return texture(shape, seed)


def test_a_gain_and_an_offset_barely_change_the_result():
    g = grey_texture()
    mask = np.ones(g.shape, np.bool_)
    brighter = np.clip(np.rint(g * 1.3 + 10), 0, 255).astype(np.uint8)
    a = normalize(g, mask, 7, 4.0, 24.0).astype(int)
    b = normalize(brighter, mask, 7, 4.0, 24.0).astype(int)
    raw = np.abs(brighter.astype(int) - g).mean()
    assert np.abs(a - b).mean() < 0.1 * raw  # the raw images differ ten times more


def test_normalize_on_a_strip_of_rows_gives_the_whole_image_rows():
    g = grey_texture((50, 70), seed=2)
    mask = np.ones(g.shape, np.bool_)
    whole = normalize(g, mask, 7, 4.0, 24.0)
    strip = normalize(g[10:40], mask[10:40], 7, 4.0, 24.0)
    np.testing.assert_array_equal(strip[3:-3], whole[13:37])  # window radius 3


def test_invalid_pixels_read_128_and_do_not_darken_their_neighbours():
    g = np.full((20, 20), 200, np.uint8)
    g[:, :5] = 0  # a rectification's black fill
    mask = np.ones(g.shape, np.bool_)
    mask[:, :5] = False
    out = normalize(g, mask, 7, 4.0, 24.0)
    assert (out[:, :5] == 128).all()
    assert (out[:, 5:] == 128).all()  # a uniform valid area stays at the middle grey

