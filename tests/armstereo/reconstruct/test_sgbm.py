"""OpenCV SGBM as the peer: its options beyond OpenCV's, and the shift-averaged sub-pixel step."""

import cv2
import numpy as np
import pytest

from armstereo.errors import StereoError
from armstereo.reconstruct.sgbm import sgbm, shift_averaged
from armstereo.reconstruct.stereo_options import SgbmOptions

FRACTIONS = (0.2, 0.25, 0.3, 0.7, 0.75, 0.8)  # where the parabola locks worst


def fractional_pair(d, *, shape=(60, 160), seed=0):
    """A fronto-parallel plane at the fractional disparity ``d``: ``right(x) = left(x + d)``,
    both sampled (bicubic) from one smooth float texture, then rounded to uint8."""
    H, W = shape
    rng = np.random.default_rng(seed)
    tex = cv2.GaussianBlur(rng.uniform(0, 255, (H, W + 40)).astype(np.float32), (0, 0), 1.2)
    tex = (tex - tex.mean()) / tex.std() * 40 + 128
    right = cv2.warpAffine(tex, np.float32([[1, 0, 20 + d], [0, 1, 0]]), (W, H),
                           flags=cv2.INTER_CUBIC | cv2.WARP_INVERSE_MAP)
    as_u8 = lambda a: np.clip(np.rint(a), 0, 255).astype(np.uint8)  # noqa: E731
    return as_u8(tex[:, 20:20 + W]), as_u8(right)


def median_error(d, **options):
    left, right = fractional_pair(d)
    disp = sgbm(left, right, 15, **options)[:, 30:-10]  # right of SGBM's empty left band
    assert np.isfinite(disp).all()
    return float(np.median(np.abs(disp - d)))


def test_the_defaults_are_opencvs_sgbm_unchanged():
    left, right = fractional_pair(6.3)
    o = SgbmOptions()
    assert (o.mode, o.presmooth, o.shifts) == ("sgbm", 0.0, 1)
    raw = cv2.StereoSGBM_create(minDisparity=0, numDisparities=16, blockSize=5, P1=200,
                                P2=800, disp12MaxDiff=1, uniquenessRatio=10,
                                speckleWindowSize=100, speckleRange=2).compute(left, right)
    want = np.where(raw < 0, np.nan, raw / 16.0).astype(np.float32)
    np.testing.assert_array_equal(sgbm(left, right, 15), want)


def test_shifts_undo_the_parabolas_locking_to_whole_disparities():
    plain = [median_error(6 + f) for f in FRACTIONS]
    shifted = [median_error(6 + f, shifts=4) for f in FRACTIONS]
    # measured: plain 0.14-0.25 px (mean 0.20), 4 shifts 0.03-0.08 px (mean 0.06)
    assert np.mean(plain) > 0.15
    assert np.mean(shifted) < 0.09 and max(shifted) < 0.1
    # one half-pixel shift already meets the other phase of the locking (measured mean 0.04)
    assert np.mean([median_error(6 + f, shifts=2) for f in FRACTIONS]) < 0.07


def test_shifts_and_presmooth_keep_whole_disparities_right():
    for options in ({}, dict(shifts=4), dict(presmooth=1.5, shifts=4)):
        assert median_error(6.0, **options) < 0.05


def test_shifts_answer_exactly_where_the_unshifted_match_does():
    left, right = fractional_pair(6.3, seed=1)
    left[20:35, 60:90] = 128  # a flat patch SGBM's uniqueness test leaves unanswered
    mask = np.ones(left.shape, bool)
    mask[:, 140:] = False
    for presmooth in (0.0, 1.5):
        one = sgbm(left, right, 15, presmooth=presmooth, left_mask=mask)
        four = sgbm(left, right, 15, presmooth=presmooth, shifts=4, left_mask=mask)
        assert (~np.isfinite(one)).any()
        np.testing.assert_array_equal(np.isfinite(four), np.isfinite(one))


def test_a_shifted_answer_far_from_the_unshifted_one_is_left_out():
    base = np.array([[5.0, 5.0, np.nan]], np.float32)
    answers = iter([base, np.array([[5.5, 9.0, 7.0]], np.float32)])
    # the shifted "match" is called with the moved right image and answers 0.5 px more
    out = shift_averaged(lambda right: next(answers), np.zeros((1, 3), np.uint8), 2)
    np.testing.assert_allclose(out, [[(5.0 + 5.0) / 2, 5.0, np.nan]])


@pytest.mark.parametrize("kwargs, message", [
    (dict(mode="fast"), "mode='fast' is not one of sgbm, hh, 3way, hh4"),
    (dict(presmooth=-1.0), "presmooth must be 0..10"),
    (dict(presmooth=float("nan")), "presmooth must be 0..10"),
    (dict(presmooth=True), "presmooth must be 0..10"),
    (dict(shifts=0), "shifts must be 1..16"),
    (dict(shifts=2.0), "shifts must be a whole number"),
])
def test_bad_sgbm_options_are_refused(kwargs, message):
    with pytest.raises(StereoError, match=message):
        SgbmOptions(**kwargs)


@pytest.mark.parametrize("mode", ["hh", "3way", "hh4"])
def test_every_opencv_mode_matches(mode):
    assert median_error(6.0, mode=mode) < 0.05
