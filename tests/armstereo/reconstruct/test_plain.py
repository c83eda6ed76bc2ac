"""Plain runs between agreeing textured ends get the line between them, when supported."""

from __future__ import annotations

import numpy as np

from armstereo.reconstruct.plain import fill_plain


def row(values, flat_from, flat_to):
    disp = np.array([values], np.float32)
    flat = np.zeros(disp.shape, np.bool_)
    flat[0, flat_from:flat_to] = True
    return disp, flat


def fill(disp, before, flat, support=0.5):
    out = disp.copy()
    fill_plain(out, before, flat, tolerance=1.0, slope=0.1, support=support)
    return out


def test_a_supported_hole_between_agreeing_ends_gets_the_straight_line():
    # a plane: disparity 10 at x = 0 rising 0.1 per pixel; x = 2..7 plain, half of them
    # answered on the plane before the flat test, all rejected by it
    truth = 10 + 0.1 * np.arange(10, dtype=np.float32)
    before, flat = row(truth, 2, 8)
    before[0, [3, 5, 7]] = np.nan
    disp = truth.copy()[None]
    disp[0, 2:8] = np.nan
    out = fill(disp, before, flat)
    np.testing.assert_allclose(out, truth[None], atol=1e-5)


def test_a_background_the_programme_did_not_support_stays_empty():
    # two ends of a foreground at 20 with a plain background between them that the
    # programme saw at 8: the ends agree, but nothing in the run supports 20
    before, flat = row([20, 20, 8, 8, 8, 8, 8, 20, 20], 2, 7)
    disp = before.copy()
    disp[0, 2:7] = np.nan
    out = fill(disp, before, flat)
    assert np.isnan(out[0, 2:7]).all()


def test_ends_that_disagree_or_a_run_at_the_image_edge_are_not_filled():
    before, flat = row([10, 10, 10, 10, 30, 30], 2, 4)  # ends at 10 and 30
    disp = before.copy()
    disp[0, 2:4] = np.nan
    assert np.isnan(fill(disp, before, flat)[0, 2:4]).all()
    before, flat = row([10, 10, 10, 10], 2, 4)  # the run reaches the right edge
    disp = before.copy()
    disp[0, 2:4] = np.nan
    assert np.isnan(fill(disp, before, flat)[0, 2:4]).all()


def test_answers_inside_the_run_are_kept_and_columns_fill_what_rows_cannot():
    disp = np.full((5, 3), 12.0, np.float32)
    flat = np.zeros(disp.shape, np.bool_)
    flat[1:4, :] = True  # whole rows plain: no row has a textured end
    before = disp.copy()
    disp[1:4, 1] = np.nan
    disp[2, 0] = 12.4  # an answer the rows keep
    out = fill(disp, before, flat)
    np.testing.assert_allclose(out[1:4, 1], 12.0)
    assert out[2, 0] == np.float32(12.4)
