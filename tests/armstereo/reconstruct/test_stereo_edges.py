"""The edge prefilter of the matched images (``prefilter="edges"``) and the occlusion rule's
margin (``occlusion_margin``), issue 14 item 2 (Cones)."""

from __future__ import annotations

import numpy as np
import pytest

from armstereo.errors import StereoError
from armstereo.evaluation.disparity import evaluate_disparity
from armstereo.reconstruct import rejection, stereo, stereo_inputs
from armstereo.reconstruct.stereo import PAPER_OPTIONS, birchfield
from tests.support.images import box_pair, texture
from tests.support.middlebury import bench_window, load_pair


@pytest.mark.parametrize("cap", [1, 12, 300])
def test_edges_adds_the_clipped_horizontal_sobel_and_saturates(cap):
    grey = texture((30, 50), seed=3, contrast=120.0)
    grey[:, 20:] = 255  # saturates where the Sobel is positive
    grey[:, :5] = 0
    sobel = np.zeros(grey.shape, np.float64)
    g = np.pad(grey.astype(np.float64), 1, mode="reflect")  # OpenCV's default border
    for dy, weight in ((0, 1), (1, 2), (2, 1)):
        sobel += weight * (g[dy:dy + 30, 2:] - g[dy:dy + 30, :-2])
    want = np.clip(grey + np.clip(sobel, -cap, cap), 0, 255)
    np.testing.assert_array_equal(stereo_inputs.with_edges(grey, cap), want.astype(np.uint8))


def test_the_edge_prefilter_applies_to_grey_matching_only_and_needs_a_positive_cap():
    """As cost_window, the default prefilter does not apply to the per-channel kernels."""
    left = texture((20, 60), seed=1, channels=3)
    right = np.ascontiguousarray(np.roll(left, -4, axis=1))
    np.testing.assert_array_equal(birchfield(left, right, 10, prefilter="edges", color="sum"),
                                  birchfield(left, right, 10, prefilter="none", color="sum"))
    left, right = (np.ascontiguousarray(img) for img in box_pair(2, 9, (20, 45, 5, 15),
                                                                 shape=(20, 60)))
    assert not np.array_equal(birchfield(left, right, 10, prefilter="edges"),
                              birchfield(left, right, 10, prefilter="none"), equal_nan=True)
    with pytest.raises(StereoError, match="edge_cap"):
        birchfield(left, right, 10, prefilter="edges", edge_cap=0)


def test_the_defaults_match_with_edges():
    assert stereo.PREFILTER == "edges"
    left = texture((30, 70), seed=6)
    right = np.ascontiguousarray(np.roll(left, -5, axis=1))
    right[:, 20:30] = texture((30, 10), seed=8)
    np.testing.assert_array_equal(birchfield(left, right, 12),
                                  birchfield(left, right, 12, prefilter="edges"))


def test_the_edge_prefilter_finds_a_shifted_plane():
    left = texture((40, 90), seed=4)
    right = np.ascontiguousarray(np.roll(left, -7, axis=1))
    disp = birchfield(left, right, 15, prefilter="edges", subpixel="none")
    assert np.mean(disp[:, 20:80] == 7) > 0.95


def test_the_papers_matcher_matches_raw_intensities_with_its_reward():
    assert PAPER_OPTIONS["prefilter"] == "none"
    assert PAPER_OPTIONS["match_reward"] == 5
    assert stereo.MATCH_REWARD == 6


def cones():
    left, right, gt, mask, meta = load_pair("cones")
    return left, right, gt, mask, bench_window(meta)


def test_edges_sharpen_the_depth_edges_of_cones():
    """Matching the intensities plus their clipped horizontal gradient moves the programme's
    depth jumps onto the objects' outlines: Cones bad-2 6.7 % -> 4.5 % on the raw views
    (stereo_accuracy.md). Cones' views differ a little in brightness, which the gradient
    also ignores: once the brightness is equalised, the edges still gain (4.5 % -> 4.0 %,
    bench/results/radiometric.md)."""
    left, right, gt, mask, n = cones()

    def bad2(prefilter, **options):
        disp = birchfield(left, right, n, prefilter=prefilter, **options)
        return evaluate_disparity(disp, gt, mask, exclude_left=n)["bad2"]

    plain, edges = bad2("none", equalize=False), bad2("edges", equalize=False)
    assert edges < 0.047
    assert plain - edges > 0.015
    plain, edges = bad2("none"), bad2("edges")
    assert edges < 0.042
    assert plain - edges > 0.003


def row_with_a_nearer_box():
    """One row: a background at disparity 10, then from x = 20 a box at 14 whose right-view
    positions ``x - 14`` start at 6: background pixels at ``x - 10 >= 6 + margin`` are hidden."""
    disp = np.full((1, 40), 10.0, np.float32)
    disp[0, 20:] = 14.0
    return disp


@pytest.mark.parametrize("margin, hidden", [(1.0, [17, 18, 19]), (3.0, [19]), (5.0, [])])
def test_the_occlusion_margin_is_how_far_behind_a_hidden_pixel_must_project(margin, hidden):
    got = np.flatnonzero(rejection.hidden_by_nearer(row_with_a_nearer_box(), margin)[0])
    np.testing.assert_array_equal(got, hidden)


def test_the_occlusion_margin_is_passed_on_and_checked():
    left = texture((30, 80), seed=2)
    right = np.ascontiguousarray(np.roll(left, -5, axis=1))
    right[:, 30:45] = texture((30, 15), seed=9)  # something for the rule to act on
    wide = birchfield(left, right, 12, occlusion_margin=50)
    narrow = birchfield(left, right, 12, occlusion_margin=0)
    assert np.isfinite(narrow).sum() < np.isfinite(wide).sum()
    with pytest.raises(StereoError, match="occlusion_margin"):
        birchfield(left, right, 12, occlusion_margin=-1)
