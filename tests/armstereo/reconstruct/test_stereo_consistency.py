"""Inter-scanline consistency (issue 14): flat pixels supported along their column, the
consensus median that replaces streaks and blobs, and the column pass on the programme's costs
(``column_smoothing``)."""

from __future__ import annotations

import numpy as np
import pytest

from armstereo.errors import StereoError
from armstereo.reconstruct import consensus, rejection
from armstereo.reconstruct.stereo import birchfield
from tests.support.images import texture

RUN = 20  # pixels: longer than the one-sided reach of rejection.unsupported


def flat_strip_from_the_border():
    """A 7x40 map: a flat run over the first 20 pixels of row 3 (no anchor on its left, and
    too long for the one-sided rule near a run's end), with textured rows above and below it
    at the same disparity."""
    disp = np.full((7, 40), 6.0, np.float32)
    flat = np.zeros((7, 40), bool)
    flat[3, :RUN] = True
    return disp, flat


def test_column_support_keeps_a_flat_run_its_column_confirms():
    disp, flat = flat_strip_from_the_border()
    row_only = rejection.unsupported(disp, flat, rejection.FLAT_TOLERANCE, columns=False)
    with_columns = rejection.unsupported(disp, flat, rejection.FLAT_TOLERANCE, columns=True)
    assert row_only[3, :RUN].all()  # no textured pixel left of the run on its row
    assert not with_columns.any()  # the textured pixels above and below agree


def test_column_support_still_rejects_what_its_column_contradicts():
    disp, flat = flat_strip_from_the_border()
    disp[3, :RUN] = 14.0  # the run invented a nearer surface than the rows around it
    assert rejection.unsupported(disp, flat, rejection.FLAT_TOLERANCE, columns=True)[3, :RUN].all()


def test_column_support_never_rejects_more_than_the_row_rule():
    rng = np.random.default_rng(3)
    disp = rng.integers(0, 4, (30, 40)).astype(np.float32)
    disp[rng.random(disp.shape) < 0.1] = np.nan
    flat = rng.random(disp.shape) < 0.6
    row_only = rejection.unsupported(disp, flat, rejection.FLAT_TOLERANCE, columns=False)
    with_columns = rejection.unsupported(disp, flat, rejection.FLAT_TOLERANCE, columns=True)
    assert not (with_columns & ~row_only).any()
    assert (row_only & ~with_columns).any()


def test_consensus_replaces_a_streak_by_its_surface():
    disp = np.full((30, 40), 10.25, np.float32)
    disp[14:16, 5:35] = 20.0  # a two-row streak at a wrong disparity
    disp[3, 3] = 11.5  # within the speckle range: left alone
    disp[25:28, 25:28] = np.nan
    consensus.replace_outliers(disp, 9, 0, 31, 2.0)
    assert np.all(disp[14:16, 5:35] == 10.0)  # the window's median, whole disparities
    assert disp[3, 3] == np.float32(11.5) and disp[0, 0] == np.float32(10.25)
    assert np.isnan(disp[25:28, 25:28]).all()  # no answer is invented


def test_consensus_leaves_pixels_whose_window_is_mostly_unanswered():
    disp = np.full((20, 20), np.nan, np.float32)
    disp[10, 10] = 7.0  # the window's median is "no answer"
    consensus.replace_outliers(disp, 9, 0, 31, 2.0)
    assert disp[10, 10] == 7.0


def test_consensus_codes_wide_windows_in_pairs_of_disparities():
    disp = np.full((30, 30), 300.0, np.float32)
    disp[10:12, :] = 100.0
    consensus.replace_outliers(disp, 9, 40, 351, 2.0)  # 352 disparities: two per code
    assert np.all(np.abs(disp[10:12] - 300.0) <= 1.0)
    assert np.all(disp[:5] == 300.0)


@pytest.mark.parametrize("size", [1, 4, -3])
def test_consensus_size_must_be_odd_and_at_least_three(size):
    img = texture((20, 60), 3)
    with pytest.raises(StereoError, match="consensus_size"):
        birchfield(img, img, 8, consensus_size=size)


@pytest.mark.parametrize("options", [dict(consensus_size=0, column_support=False),
                                     dict(consensus_size=9, column_support=True)])
def test_answers_stay_in_the_window_with_or_without_consistency(options):
    left = texture((60, 120), 5)
    right = np.roll(left, -6, axis=1)
    disp = birchfield(left, right, 15, min_disparity=2, **options)
    ok = np.isfinite(disp)
    assert ok.mean() > 0.5
    assert np.all((disp[ok] >= 2) & (disp[ok] <= 17))
    assert np.median(disp[ok]) == pytest.approx(6.0, abs=0.25)


@pytest.mark.parametrize("smoothing", [None, (1, 4)])
def test_column_smoothing_finds_a_fronto_parallel_plane(smoothing):
    left = texture((60, 120), 5)
    right = np.roll(left, -6, axis=1)
    disp = birchfield(left, right, 15, column_smoothing=smoothing, threads=1)
    ok = np.isfinite(disp[:, 20:-8])
    assert ok.mean() > 0.9
    assert np.mean(np.abs(disp[:, 20:-8][ok] - 6.0) <= 1.0) > 0.97


def test_column_smoothing_takes_its_disparity_from_the_rows_around_it():
    """Dense matching (no texture rule) of a band whose rows have no texture: the column pass
    carries the plane's disparity into it, the rows alone do not know it."""
    left = texture((60, 120), 7)
    right = np.roll(left, -6, axis=1)
    left[26:34] = 128
    right[26:34] = 128
    dense = dict(texture_threshold=0.0, reward_texture=0.0, speckle_size=0, consensus_size=0,
                 occlusions="fill", subpixel="none", threads=1)
    smooth = birchfield(left, right, 15, column_smoothing=(1, 4), **dense)
    band = smooth[27:33, 20:-8]
    assert np.mean(np.abs(band - 6.0) <= 1.0) > 0.95


def test_column_smoothing_matches_the_masked_pixels_of_neither_view():
    left = texture((40, 90), 9)
    right = np.roll(left, -5, axis=1)
    lmask = np.ones(left.shape, bool)
    lmask[:, 70:] = False
    disp = birchfield(left, right, 10, column_smoothing=(1, 4), left_mask=lmask, threads=1)
    assert np.isnan(disp[:, 70:]).all()
    ok = np.isfinite(disp)
    assert np.all((disp[ok] >= 0) & (disp[ok] <= 10))


@pytest.mark.parametrize("bad", [(4, 1), (-1, 2), (1,), "x"])
def test_column_smoothing_needs_two_ordered_penalties(bad):
    img = texture((20, 60), 3)
    with pytest.raises(StereoError, match="column_smoothing"):
        birchfield(img, img, 8, column_smoothing=bad)


def test_column_smoothing_needs_the_grey_exact_programme():
    img = texture((20, 60), 3)
    with pytest.raises(StereoError, match="column_smoothing"):
        birchfield(img, img, 8, column_smoothing=(1, 4), search="pruned")
