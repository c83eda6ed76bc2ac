"""Properties of the public matcher ``birchfield`` that hold for any setting of its options
(docs/birchfield-tomasi.md §2, §7, §8), under Hypothesis: a surface is found at every
disparity of the search window, both ends included; the occlusion penalty and match reward
are taken in grey levels as documented; the sub-pixel step never moves a disparity by more
than its bound; the left-right check reads each image's own validity mask.

Written against documented behaviour and the options as passed, not against the defaults'
values, so retuning a default does not break them.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import settings as hyp_settings
from hypothesis import strategies as st

from armstereo.reconstruct.birchfield.common.states import BORDER
from armstereo.reconstruct.birchfield.paper.matcher import DP_EXACT, DP_PRUNED, match_image
from armstereo.reconstruct.birchfield.refine import left_right_mismatch
from armstereo.reconstruct.birchfield.window.aggregate import match_image_aggregated
from armstereo.reconstruct.stereo import PAPER_OPTIONS, birchfield
from armstereo.reconstruct.subpixel import SUBPIXEL_MAX_SHIFT
from tests.armstereo.reconstruct.test_stereo import fractional_pair, shifted_pair
from tests.support.images import box_pair
from tests.support.properties import examples

# The paper's single-pixel programme and its own answer: no postprocessing, no rejections.
# the paper's matcher without its postprocessing; the tests give the penalty and reward
RAW = {k: v for k, v in dict(PAPER_OPTIONS, postprocess=False).items() if k != "match_reward"}
PARABOLA_MAX_SHIFT = 0.5  # the vertex of a parabola whose middle sample is the lowest


# --- the search window ----------------------------------------------------------------------

@hyp_settings(max_examples=examples(30))
@given(min_d=st.integers(0, 8), max_d=st.integers(1, 20), where=st.floats(0.0, 1.0),
       end=st.sampled_from(["low", "high", "inside"]), seed=st.integers(0, 50),
       search=st.sampled_from(["exact", "exact", "pruned"]), colour=st.sampled_from([1, 3]))
def test_a_plane_is_found_at_every_disparity_of_the_window(min_d, max_d, where, end, seed,
                                                           search, colour):
    """The window is ``min_disparity .. min_disparity + max_disparity``, both ends included."""
    d0 = {"low": min_d, "high": min_d + max_d,
          "inside": min_d + round(where * max_d)}[end]
    left, right = shifted_pair(d0, shape=(24, 70), seed=seed, channels=colour)
    disp = birchfield(left, right, max_d, min_disparity=min_d, search=search, subpixel="none")
    np.testing.assert_array_equal(disp[:, d0:], d0)
    assert np.isnan(disp[:, :d0]).all()  # no partner inside the right image


# --- the occlusion penalty and match reward, in grey levels ----------------------------------

def kernel_disparity(left, right, max_d, min_d, occ, rew, colour_mode, search="exact"):
    """The scanline programme run directly in its internal (doubled integer) units: grey
    exact matching runs on the row kernel of aggregate.py (a 1x1 window), the rest on the
    paper's per-pixel kernels."""
    img_l = left if left.ndim == 3 else left[:, :, None]
    img_r = right if right.ndim == 3 else right[:, :, None]
    mask = np.ones(img_l.shape[:2], np.bool_)
    if colour_mode == "gray" and search == "exact":
        out = match_image_aggregated(np.ascontiguousarray(left), np.ascontiguousarray(right),
                                     mask, mask, min_d, max_d + 1, occ, rew, 0, 0, threads=1)
        idx, state = out["disp"], out["state"]
        disp = (idx + min_d).astype(np.float32)
        disp[(idx < 0) | (state >= BORDER)] = np.nan
        return disp
    idx, state = match_image(np.ascontiguousarray(img_l), np.ascontiguousarray(img_r), mask,
                             mask, min_d, max_d + 1, occ, rew,
                             combine_max=colour_mode == "max",
                             mode=DP_EXACT if search == "exact" else DP_PRUNED, threads=1)
    disp = (idx + min_d).astype(np.float32)
    disp[(idx < 0) | (state >= BORDER)] = np.nan
    return disp


halves = st.integers(0, 120).map(lambda k: k / 2)  # grey levels, so that units stay exact


def low_contrast(img: np.ndarray, contrast: float) -> np.ndarray:
    """``img`` with its contrast around mid-grey scaled: on faint texture the reward counts."""
    return np.clip(np.rint(128 + (img.astype(float) - 128) * contrast), 0, 255).astype(np.uint8)


@hyp_settings(max_examples=examples(30))
@given(penalty=halves, reward=st.integers(0, 40).map(lambda k: k / 2),
       colour_mode=st.sampled_from(["gray", "sum", "max"]), seed=st.integers(0, 30),
       d_bg=st.integers(0, 4), d_fg=st.integers(5, 12), min_d=st.integers(0, 2),
       contrast=st.sampled_from([1.0, 0.3, 0.2]),
       search=st.sampled_from(["exact", "exact", "pruned"]))
def test_penalty_and_reward_are_grey_levels(penalty, reward, colour_mode, seed, d_bg, d_fg,
                                            min_d, contrast, search):
    """docs §2: costs, penalty and reward are grey levels at the API; the programme works in
    doubled units (2 C for C summed channels), so birchfield() hands it 2 x (or 2 C x) them."""
    left, right = (low_contrast(img, contrast) for img in box_pair(
        d_bg + min_d, d_fg + min_d, (30, 55, 5, 25), shape=(30, 90), seed=seed))
    if colour_mode != "gray":
        left, right = (np.dstack([img, np.roll(img, 7, axis=1), 255 - img]) for img in
                       (left, right))
    units = 2 * (3 if colour_mode == "sum" else 1)
    max_d = 14
    got = birchfield(left, right, max_d, min_disparity=min_d, occlusion_penalty=penalty,
                     match_reward=reward, color=colour_mode, search=search, **RAW)
    want = kernel_disparity(left, right, max_d, min_d, round(penalty * units),
                            round(reward * units), colour_mode, search)
    np.testing.assert_array_equal(got, want)


def test_the_penalty_test_can_tell_grey_levels_from_internal_units():
    """On this faint scene a penalty taken in internal units (half as large) or a reward taken
    in them changes the answer, so the property above would catch either."""
    left, right = (low_contrast(img, 0.2) for img in box_pair(1, 9, (30, 55, 5, 25),
                                                                 shape=(30, 90), seed=1))
    documented = kernel_disparity(left, right, 14, 0, 2 * 25, 2 * 5, "gray")
    assert not np.array_equal(documented, kernel_disparity(left, right, 14, 0, 25, 2 * 5, "gray"),
                              equal_nan=True)
    assert not np.array_equal(documented, kernel_disparity(left, right, 14, 0, 2 * 25, 5, "gray"),
                              equal_nan=True)
    np.testing.assert_array_equal(birchfield(left, right, 14, occlusion_penalty=25,
                                             match_reward=5, **RAW), documented)


# --- the sub-pixel step -----------------------------------------------------------------------

@hyp_settings(max_examples=examples(25))
@given(d_true=st.floats(0.0, 24.0), max_d=st.integers(4, 20), radius=st.integers(0, 6),
       mode=st.sampled_from(["gradient", "parabola"]), seed=st.integers(0, 30),
       occlusions=st.sampled_from(["nan", "fill"]))
def test_the_subpixel_step_stays_within_its_bound(d_true, max_d, radius, mode, seed,
                                                  occlusions):
    """Refinement moves an integer answer by at most its bound and answers exactly where the
    integer map does, also when the surface lies outside the window (where a gradient step
    would run off towards it); the one exception is a pixel so near the left edge that the
    refined partner ``x - d`` left the right image (documented: no answer there)."""
    left, right = fractional_pair(d_true, shape=(30, 80), seed=seed)
    # speckle removal and the consensus median run after the refinement, on the refined
    # values: left out here
    kw = dict(occlusions=occlusions, subpixel_radius=radius, speckle_size=0, consensus_size=0)
    coarse = birchfield(left, right, max_d, subpixel="none", **kw)
    fine = birchfield(left, right, max_d, subpixel=mode, **kw)
    bound = SUBPIXEL_MAX_SHIFT if mode == "gradient" else PARABOLA_MAX_SHIFT
    assert not (np.isfinite(fine) & np.isnan(coarse)).any()
    lost = np.isnan(fine) & np.isfinite(coarse)
    xs = np.broadcast_to(np.arange(coarse.shape[1]), coarse.shape)
    assert (xs[lost] - coarse[lost] - bound < -0.5).all()
    assert np.nanmax(np.abs(fine - coarse), initial=0.0) <= bound + 1e-6


def test_the_subpixel_bound_is_reached_when_the_surface_is_beyond_the_window():
    """A plane 2.4 px beyond the window's far end: the integer answer sits at the end, the
    gradient step heads for the plane and stops at the bound (so the test above is not
    vacuous)."""
    left, right = fractional_pair(17.4, shape=(40, 100))
    # the consensus median runs after the refinement, on the refined values: left out here
    coarse = birchfield(left, right, 15, subpixel="none", consensus_size=0)
    fine = birchfield(left, right, 15, subpixel="gradient", consensus_size=0)
    shift = np.abs(fine - coarse)
    assert np.nanmax(shift) == np.float32(SUBPIXEL_MAX_SHIFT)


# --- the left-right check and the validity masks ---------------------------------------------

# Answers may be off this close to the end of a valid run when the window reaches WINDOW_SLACK
# past the true disparity (a row's programme starts by matching the first right pixel).
MASK_EDGE_PX = 4
# Near the end of a valid run the row-summed programme sometimes gives up a few pixels (NaN,
# never a wrong answer): this share of the inner pixels must still answer.
MIN_INNER_ANSWERED = 0.95
WINDOW_SLACK = 2


@hyp_settings(max_examples=examples(15))
@given(d0=st.integers(6, 12), left_cut=st.integers(10, 40), right_cut=st.integers(80, 110),
       seed=st.integers(0, 30))
def test_the_left_right_check_uses_each_images_own_mask(d0, left_cut, right_cut, seed):
    """Rectification fill on the left of the left image and on the right of the right image:
    left pixels that are real and whose partner is real keep their disparity through the
    mirrored check (but for a few near the ends of the valid runs, which may be left
    unanswered); no answer comes from or points to fill."""
    left, right = shifted_pair(d0, shape=(30, 130), seed=seed)
    lmask = np.ones(left.shape, bool)
    rmask = np.ones(right.shape, bool)
    lmask[:, :left_cut] = False
    rmask[:, right_cut:] = False
    disp = birchfield(left, right, d0 + WINDOW_SLACK, lr_check=True, subpixel="none",
                      left_mask=lmask, right_mask=rmask)
    xs = np.arange(left.shape[1])
    inner = (xs >= left_cut + MASK_EDGE_PX) & (xs < right_cut + d0 - MASK_EDGE_PX)
    answered = np.isfinite(disp[:, inner])
    np.testing.assert_array_equal(disp[:, inner][answered], d0)
    assert answered.mean() >= MIN_INNER_ANSWERED
    assert np.isnan(disp[~lmask]).all()
    ys, xl = np.nonzero(np.isfinite(disp))
    assert rmask[ys, xl - disp[ys, xl].astype(int)].all()


def test_the_left_right_check_allows_one_pixel_as_documented(monkeypatch):
    """docs §8: the mirrored match may disagree by one pixel, not more."""
    import armstereo.reconstruct.stereo as stereo

    seen = []
    real = stereo.left_right_mismatch

    def spy(disp_l, disp_r, dmin, tolerance):
        seen.append(tolerance)
        return real(disp_l, disp_r, dmin, tolerance)

    monkeypatch.setattr(stereo, "left_right_mismatch", spy)
    left, right = shifted_pair(4, shape=(10, 40))
    birchfield(left, right, 8, lr_check=True)
    assert seen == [1]


def test_range_and_width_errors_name_the_numbers():
    import pytest

    from armstereo.errors import StereoError

    img = np.zeros((4, 40), np.uint8)
    with pytest.raises(StereoError, match="min_disparity \\+ max_disparity = 42 must be < the "
                                          "image width 40"):
        birchfield(img, img, 30, min_disparity=12)
    wide = np.zeros((1, 40_000), np.uint8)
    with pytest.raises(StereoError, match=r"\(1 channel\(s\) summed, occlusion penalty 25\)"):
        # the per-pixel exact programme (the row-summed default rescales its costs instead)
        birchfield(wide, wide, 8, occlusion_penalty=25, cost_window=(1, 1), slant_penalty=None)


# The matcher's answer without anything after the programme: whole disparities or NaN. On the
# intensities: the edge image of a mirrored view is not the mirrored edge image (the Sobel
# changes sign), so the mirrored pair would not be the right-to-left pass of the same costs.
WHOLE = dict(subpixel="none", postprocess="none", texture_threshold=0.0, occlusions="fill",
             speckle_size=0, consensus_size=0, reward_texture=0.5, prefilter="none")


def window_index(disp: np.ndarray, min_d: int) -> np.ndarray:
    """Whole disparities as the matcher's window indices, -1 for none."""
    return np.ascontiguousarray(np.where(np.isfinite(disp), disp - min_d, -1), dtype=np.int32)


@pytest.mark.parametrize("seed, min_d, reward_texture", [(0, 0, 0.5), (1, 2, 0.5), (2, 0, 0.0)])
def test_the_left_right_check_matches_the_mirrored_pair_with_its_own_reward(seed, min_d,
                                                                            reward_texture):
    """The right-to-left pass is the same matcher run on the mirrored, swapped pair, flat pixels
    of the right image earning no reward where they are (or every pixel rewarded, with
    reward_texture 0 as in the paper): the check rejects exactly the left answers that the
    mirrored pair's answer contradicts by more than one pixel."""
    left, right = (img.copy() for img in box_pair(2, 10, (40, 80, 10, 40), shape=(50, 110),
                                                  seed=seed))
    left[:, 60:75], right[:, 50:65] = 120, 120  # flat stripes: no reward there
    left[:, 90:105], right[:, 85:100] = 60, 60
    options = dict(WHOLE, reward_texture=reward_texture, min_disparity=min_d)
    plain = birchfield(left, right, 12, **options)
    mirrored = birchfield(np.ascontiguousarray(right[:, ::-1]),
                          np.ascontiguousarray(left[:, ::-1]), 12, **options)[:, ::-1]
    contradicted = left_right_mismatch(window_index(plain, min_d), window_index(mirrored, min_d),
                                       min_d, 1)
    checked = birchfield(left, right, 12, lr_check=True, **options)
    np.testing.assert_array_equal(checked, np.where(contradicted, np.nan, plain))
    assert 0 < contradicted.mean() < 0.5
