"""The public matcher ``armstereo.reconstruct.stereo.birchfield`` on scenes with known answers
(docs/birchfield-tomasi.md §10.3), its input checks, and a sanity bound on a Middlebury pair."""

from __future__ import annotations

import subprocess
import sys

import cv2
import numpy as np
import pytest

from armstereo.errors import StereoError
from armstereo.evaluation.disparity import evaluate_disparity
from armstereo.reconstruct import stereo
from armstereo.reconstruct.stereo import PAPER_OPTIONS, birchfield, compute_disparity, sgbm
from tests.support.images import box_pair, texture
from tests.support.middlebury import load_pair

# Measured 3.49 % (bench/results/stereo.md); the bound leaves room for tie-breaking changes,
# not for a broken matcher.
TSUKUBA_BAD2_BOUND = 0.06


def shifted_pair(d0, *, shape=(60, 120), seed=0, channels=1):
    """Left and right views of one fronto-parallel plane at disparity ``d0``:
    ``left[:, x] = right[:, x - d0]``."""
    H, W = shape
    tex = texture((H, W + d0), seed, channels=channels)
    return tex[:, :W], tex[:, d0:]


def fractional_pair(d0: float, *, shape=(60, 140), seed=3):
    """A fronto-parallel plane at a fractional disparity ``d0``: the right view is the left
    texture resampled ``d0`` px to the left (``right(x) = left(x + d0)``, cubic)."""
    H, W = shape
    tex = texture((H, W + 20), seed, blur=2.0).astype(np.float32)
    left = tex[:, :W]
    xs, ys = np.meshgrid(np.arange(W, dtype=np.float32) + np.float32(d0),
                         np.arange(H, dtype=np.float32))
    right = cv2.remap(tex, xs, ys, cv2.INTER_CUBIC)
    return (np.clip(np.rint(left), 0, 255).astype(np.uint8),
            np.clip(np.rint(right), 0, 255).astype(np.uint8))


# --- known answers ------------------------------------------------------------------------

@pytest.mark.parametrize("d0", [0, 5, 12])
@pytest.mark.parametrize("channels", [1, 3])
def test_constant_disparity_recovered_exactly(d0, channels):
    left, right = shifted_pair(d0, channels=channels)
    disp = birchfield(left, right, 15, subpixel="none")
    assert np.isnan(disp[:, :d0]).all()  # no partner inside the right image
    np.testing.assert_array_equal(disp[:, d0:], d0)
    # the default subpixel refinement keeps an exact integer shift where it is
    refined = birchfield(left, right, 15)
    np.testing.assert_allclose(refined[:, d0 + 2:-2], d0, atol=1e-3)


def test_min_disparity_shifts_the_window():
    left, right = shifted_pair(14, seed=3)
    disp = birchfield(left, right, 6, min_disparity=10, subpixel="none")
    np.testing.assert_array_equal(disp[:, 14:], 14)
    assert np.isnan(disp[:, :10]).all()  # x < min_disparity can never have a partner


def test_fronto_parallel_box_interiors_exact_and_occlusion_strip_where_geometry_says():
    d_bg, d_fg, (x0, x1, y0, y1) = 3, 11, (50, 100, 20, 60)
    left, right = box_pair(d_bg, d_fg, (x0, x1, y0, y1))
    # a margin of one pixel: every pixel of the strip projects behind the box (the default
    # margin keeps the background's disparity on the strip's first d_fg - d_bg - 3 pixels)
    disp = birchfield(left, right, 15, subpixel="none", occlusion_margin=1)
    m = 3  # boundaries may be off by a pixel or two (docs/birchfield-tomasi.md §10.3)
    np.testing.assert_array_equal(disp[y0 + m:y1 - m, x0 + m:x1 - m], d_fg)
    np.testing.assert_array_equal(disp[y0 + m:y1 - m, d_bg + m:x0 - (d_fg - d_bg) - m], d_bg)
    np.testing.assert_array_equal(disp[y0 + m:y1 - m, x1 + m:], d_bg)
    np.testing.assert_array_equal(disp[:y0 - m, d_bg:], d_bg)
    np.testing.assert_array_equal(disp[y1 + m:, d_bg:], d_bg)
    # Left pixels x0 - 8 .. x0 - 1 see background that the box hides from the right camera:
    # no disparity there, and nowhere else inside the box's rows (away from the left border).
    strip = np.zeros(left.shape[1], bool)
    strip[x0 - (d_fg - d_bg):x0] = True
    near_strip = strip | np.roll(strip, 1) | np.roll(strip, -1)
    for row in disp[y0 + m:y1 - m]:
        missing = np.isnan(row)
        missing[:d_bg] = False
        assert (missing & strip).sum() >= strip.sum() - 1
        assert not (missing & ~near_strip).any()
    default = birchfield(left, right, 15, subpixel="none")
    kept = x0 - (d_fg - d_bg) + np.arange(d_fg - d_bg - stereo.OCCLUSION_MARGIN + 1)
    np.testing.assert_array_equal(default[y0 + m:y1 - m][:, kept.astype(int)], d_bg)
    # the paper's own policy fills the strip with the background disparity instead
    filled = birchfield(left, right, 15, subpixel="none", occlusions="fill")
    np.testing.assert_array_equal(filled[y0 + m:y1 - m, x0 - (d_fg - d_bg) + 1:x0 - 1], d_bg)


def test_left_right_check_also_rejects_the_occluded_strip():
    d_bg, d_fg, box = 2, 10, (60, 110, 15, 55)
    left, right = box_pair(d_bg, d_fg, box, seed=4)
    disp = birchfield(left, right, 15, occlusions="fill", lr_check=True, subpixel="none")
    x0 = box[0]
    assert np.isnan(disp[20:50, x0 - 6:x0 - 2]).all()
    assert np.isfinite(disp[20:50, x0 + 3:box[1] - 3]).all()


def test_flat_pair_gives_the_smallest_disparity_in_the_paper_and_none_by_default():
    flat = np.full((30, 50), 90, np.uint8)
    np.testing.assert_array_equal(birchfield(flat, flat, 8, **PAPER_OPTIONS), 0)
    disp = birchfield(flat, flat, 8, min_disparity=3, **PAPER_OPTIONS)
    assert np.isnan(disp[:, :3]).all()
    np.testing.assert_array_equal(disp[:, 3:], 3)
    # by default nothing is invented where there is nothing to match
    assert np.isnan(birchfield(flat, flat, 8)).all()


def test_grey_and_colour_inputs_agree_on_a_grey_scene():
    left, right = shifted_pair(7, seed=5)
    grey = birchfield(left, right, 15)
    bgr = birchfield(cv2.cvtColor(left, cv2.COLOR_GRAY2BGR), cv2.cvtColor(right,
                     cv2.COLOR_GRAY2BGR), 15)
    np.testing.assert_array_equal(grey, bgr)


def test_threads_do_not_change_the_result():
    left, right = box_pair(2, 9, (40, 90, 10, 50), seed=6)
    np.testing.assert_array_equal(birchfield(left, right, 15, threads=1),
                                  birchfield(left, right, 15, threads=2))


def test_masked_pixels_get_no_disparity():
    left, right = shifted_pair(4, seed=7)
    lmask = np.ones(left.shape, bool)
    lmask[:, 100:] = False  # e.g. rectification fill on the right side of the left image
    disp = birchfield(left, right, 15, left_mask=lmask, subpixel="none")
    assert np.isnan(disp[:, 100:]).all()
    np.testing.assert_array_equal(disp[:, 4:100], 4)


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="counts threads in /proc")
def test_no_worker_threads_left_running():
    """Rows run on short-lived Python threads, not on numba's parallel layer, whose OpenMP
    workers would stay behind spinning and slow the OpenCV/numpy stages that follow. A fresh
    process, so that no earlier call has started such workers: numba's threading layer must
    never start, no Python thread may outlive the call, and a second call adds no native
    thread (the first one may start OpenCV's own pool, which every OpenCV stage shares)."""
    code = (
        "import os, threading, time, numba, numpy as np\n"
        "from armstereo.reconstruct.stereo import birchfield\n"
        "img = np.random.default_rng(0).integers(0, 255, (40, 80), dtype=np.uint8)\n"
        "def settled(before):\n"
        # a joined thread can still be listed for a moment while the OS reaps it
        "    for _ in range(100):\n"
        "        if len(os.listdir('/proc/self/task')) <= before: break\n"
        "        time.sleep(0.01)\n"
        "    return len(os.listdir('/proc/self/task'))\n"
        "birchfield(img, img, 8, threads=2)\n"
        "first = settled(0)\n"
        "birchfield(img, img, 8, threads=2)\n"
        "try:\n"
        "    layer = numba.threading_layer()\n"
        "except ValueError:\n"
        "    layer = 'none'\n"
        "print(first, settled(first), threading.active_count(), layer)\n")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=300, check=True)
    first, second, python_threads, layer = proc.stdout.split()
    assert layer == "none"
    assert python_threads == "1"
    assert second == first


# --- bad input ------------------------------------------------------------------------------

GOOD = np.zeros((20, 40), np.uint8)


@pytest.mark.parametrize("match", [birchfield, sgbm])
@pytest.mark.parametrize("left, right, max_disparity, message", [
    (GOOD, np.zeros((20, 41), np.uint8), 8, "sizes differ"),
    (GOOD, np.zeros((20, 40, 3), np.uint8), 8, "sizes differ"),
    (np.zeros((0, 40), np.uint8), np.zeros((0, 40), np.uint8), 8, "empty"),
    (GOOD, np.zeros((20, 0), np.uint8), 8, "empty"),
    (GOOD.astype(np.float32), GOOD, 8, "uint8"),
    (np.zeros((20, 40, 4), np.uint8), np.zeros((20, 40, 4), np.uint8), 8, "BGR"),
    ([[0]], GOOD, 8, "numpy array"),
    (GOOD, GOOD, 0, "max_disparity must be >= 1"),
    (GOOD, GOOD, -3, "max_disparity must be >= 1"),
    (GOOD, GOOD, 40, "must be < the image width 40"),
    (GOOD, GOOD, 8.0, "must be an integer"),
])
def test_bad_input_is_a_clear_stereo_error(match, left, right, max_disparity, message):
    with pytest.raises(StereoError, match=message):
        match(left, right, max_disparity)


@pytest.mark.parametrize("kwargs, message", [
    (dict(min_disparity=-1), "min_disparity must be >= 0"),
    (dict(min_disparity=35), "must be < the image width"),
    (dict(color="rgb"), "color='rgb' is not one of"),
    (dict(subpixel="cubic"), "subpixel"),
    (dict(search="greedy"), "search"),
    (dict(occlusions="zero"), "occlusions"),
    (dict(occlusion_penalty=-1), "must be >= 0"),
    (dict(threads=0), "threads must be >= 1"),
    (dict(left_mask=np.ones((5, 5), bool)), "left_mask has shape"),
])
def test_bad_options_are_clear_stereo_errors(kwargs, message):
    with pytest.raises(StereoError, match=message):
        birchfield(GOOD, GOOD, 8, **kwargs)


def test_rows_too_wide_for_exact_colour_sums_are_refused():
    wide = np.zeros((1, 40_000, 3), np.uint8)  # summed channels are exact up to ~11,000 px
    with pytest.raises(StereoError, match="exceeds .* the widest row"):
        birchfield(wide, wide, 8, color="sum")


def test_very_wide_rows_are_matched_with_divided_costs():
    """The default kernel divides its summed costs to stay exact in float32 (cost_divisor)."""
    left, right = shifted_pair(5, shape=(3, 40_000), seed=12)
    disp = birchfield(left, right, 8, subpixel="none")
    assert np.mean(disp[:, 5:] == 5) > 0.99


def test_unknown_method_is_a_stereo_error():
    with pytest.raises(StereoError, match="unknown stereo method 'bm'"):
        compute_disparity(GOOD, GOOD, 8, method="bm")


# --- a real pair ----------------------------------------------------------------------------

def test_tsukuba_bad2_below_the_measured_bound():
    left, right, gt, mask, meta = load_pair("tsukuba")
    disp = birchfield(left, right, meta["max_disp"])
    scores = evaluate_disparity(disp, gt, mask, exclude_left=meta["max_disp"])
    assert scores["bad2"] < TSUKUBA_BAD2_BOUND
    assert scores["median_error"] < 0.5


@pytest.mark.parametrize("d0", [6.3, 9.5, 12.4])
def test_default_subpixel_step_recovers_a_fractional_disparity(d0):
    """The default refinement must run and must move integer answers towards the truth."""
    left, right = fractional_pair(d0)
    inner = (slice(5, -5), slice(20, -10))  # away from the borders and the unmatched band
    coarse = birchfield(left, right, 15, subpixel="none")[inner]
    fine = birchfield(left, right, 15)[inner]
    assert np.isfinite(fine).mean() > 0.95
    assert np.nanmedian(np.abs(coarse - d0)) >= 0.25  # integer labels: 0.3-0.5 px off
    assert np.nanmedian(np.abs(fine - d0)) < 0.08  # measured 0.006-0.05 px


# --- contracts the mutation run (bench/results/mutation.md) found untested --------------------

def test_options_are_keyword_only_and_the_inputs_may_be_named():
    left, right = shifted_pair(4, shape=(20, 40), seed=8)
    with pytest.raises(TypeError):
        birchfield(left, right, 8, 2)  # a bare number is not silently taken as min_disparity
    np.testing.assert_array_equal(birchfield(left=left, right=right, max_disparity=8),
                                  birchfield(left, right, 8))


def runtime(text: str) -> str:
    """The same text as a new string object, as read from a config file or the command line
    (a literal in this file would be the interned object the module compares against)."""
    out = "".join(list(text))
    assert out == text and out is not text
    return out


@pytest.mark.parametrize("options", [
    dict(color="gray", search="exact"),  # the default summed-window kernel
    dict(PAPER_OPTIONS, color="gray", search="exact"),  # the paper's exact programme
])
def test_option_strings_are_compared_by_value(options):
    left, right = box_pair(1, 9, (30, 55, 5, 25), shape=(30, 90), seed=1)
    literal = birchfield(left, right, 14, **options)
    read = birchfield(left, right, 14, **{k: runtime(v) if isinstance(v, str) else v
                                          for k, v in options.items()})
    np.testing.assert_array_equal(read, literal)


def test_the_option_string_test_can_tell_the_kernels_apart():
    """On that scene the kernels a misread option would select answer differently."""
    left, right = box_pair(1, 9, (30, 55, 5, 25), shape=(30, 90), seed=1)
    default = birchfield(left, right, 14)
    assert not np.array_equal(default, birchfield(left, right, 14, cost_window=(1, 1),
                                                  slant_penalty=None), equal_nan=True)
    paper = birchfield(left, right, 14, **PAPER_OPTIONS)
    assert not np.array_equal(paper, birchfield(left, right, 14, **dict(PAPER_OPTIONS,
                                                                        search="pruned")),
                              equal_nan=True)


def test_the_default_match_reward_is_the_documented_6_grey_levels():
    # imported here: test_stereo_properties imports this module
    from tests.armstereo.reconstruct.test_stereo_properties import low_contrast

    left, right = (low_contrast(img, 0.2) for img in box_pair(1, 9, (30, 55, 5, 25),
                                                                 shape=(30, 90), seed=2))
    # on the intensities: the edge prefilter leaves this low-contrast box without a tie that
    # the reward decides
    default = birchfield(left, right, 14, prefilter="none")
    np.testing.assert_array_equal(default, birchfield(left, right, 14, match_reward=6,
                                                      prefilter="none"))
    assert not np.array_equal(default, birchfield(left, right, 14, match_reward=5,
                                                  prefilter="none"), equal_nan=True)


def test_highpass_prefilter_runs_on_grey_matching():
    left, right = shifted_pair(6, shape=(40, 80), seed=9)
    disp = birchfield(left, right, 10, prefilter="highpass", color="gray", subpixel="none")
    assert np.mean(disp[:, 6:] == 6) > 0.95
    with pytest.raises(StereoError, match="grey matching only"):
        birchfield(left, right, 10, prefilter="highpass", color="sum")


def test_the_median_treats_the_windows_lowest_disparity_like_any_other():
    """A surface at 5.3 px found at the bottom of the window (5 .. 11) or inside it (4 .. 10):
    the same answer, postprocessing included."""
    left, right = fractional_pair(5.3)
    low = birchfield(left, right, 6, min_disparity=5)
    inside = birchfield(left, right, 6, min_disparity=4)
    ok = np.isfinite(low) & np.isfinite(inside)
    assert ok.mean() > 0.9
    np.testing.assert_allclose(low[ok], inside[ok], rtol=0, atol=1e-5)


def test_a_match_on_the_right_images_first_column_is_kept_with_a_mask():
    # the left pixel x = d matches right column 0; a right mask elsewhere must not drop it
    left, right = shifted_pair(4, shape=(30, 60), seed=10)
    rmask = np.ones(right.shape, bool)
    rmask[:, 50:] = False  # e.g. rectification fill on the right side of the right image
    disp = birchfield(left, right, 8, right_mask=rmask, subpixel="none")
    np.testing.assert_array_equal(disp[:, 4:40], 4)


def test_images_with_more_than_three_dimensions_are_refused():
    img = np.zeros((20, 40, 1, 1), np.uint8)
    with pytest.raises(StereoError, match=r"\(H, W\) grey or \(H, W, 3\) BGR"):
        birchfield(img, img, 8)


def test_too_wide_rows_message_names_the_penalty_in_grey_levels():
    wide = np.zeros((1, 40_000, 3), np.uint8)
    with pytest.raises(StereoError, match=r"3 channel\(s\) summed, occlusion penalty 25\)"):
        birchfield(wide, wide, 8, color="sum")
