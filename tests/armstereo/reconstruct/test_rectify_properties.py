"""Rectification contracts that the mutation run showed untested (docs/rectification.md):
which view becomes the left image for every baseline direction, the validity mask of a warp,
and a forced canvas size that stays centred on the warped images."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given
from hypothesis import settings as hyp_settings
from hypothesis import strategies as st

from armstereo.reconstruct.rectify import (
    MAP_TOLERANCE,
    _axis_window,
    _warp,
    second_view_is_left,
)
from armstereo.transforms import make_T
from tests.support.geometry import random_rotation
from tests.support.properties import examples


@hyp_settings(max_examples=examples(60))
@given(angle=st.one_of(st.floats(-180.0, 180.0), st.sampled_from([-90.0, 90.0, 0.0, 180.0])),
       depth=st.floats(-0.5, 0.5), seed=st.integers(0, 1000))
def test_view_1_stays_left_exactly_for_image_plane_angles_in_minus_90_to_90(angle, depth, seed):
    """The baseline seen in camera 1 at image-plane angle a: view 1 is the left image when a
    lies in (-90, 90] deg, so the rectified images turn by at most 90 deg."""
    R = random_rotation(np.random.default_rng(seed))
    c1 = np.array([0.3, -0.2, 0.5])
    a = math.radians(angle)
    b_cam = np.array([math.cos(a), math.sin(a), depth]) * 0.1
    if angle in (-90.0, 90.0):
        b_cam[0] = 0.0  # straight up or down in the image, exactly
    T1, T2 = make_T(R, c1), make_T(R, c1 + R @ b_cam)
    measured = math.degrees(math.atan2((R.T @ (T2[:3, 3] - c1))[1],
                                       (R.T @ (T2[:3, 3] - c1))[0]))
    assert second_view_is_left(T1, T2) == (not -90.0 < measured <= 90.0)


def test_a_baseline_straight_up_the_image_makes_view_2_the_left_one():
    T1 = np.eye(4)
    assert second_view_is_left(T1, make_T(np.eye(3), [0.0, -0.1, 0.0]))
    assert not second_view_is_left(T1, make_T(np.eye(3), [0.0, 0.1, 0.0]))


@hyp_settings(max_examples=examples(30))
@given(w=st.integers(2, 30), h=st.integers(2, 30), seed=st.integers(0, 1000))
def test_the_warp_mask_marks_exactly_the_samples_inside_the_source(w, h, seed):
    rng = np.random.default_rng(seed)
    mx = rng.uniform(-3.0, w + 2.0, (12, 16)).astype(np.float32)
    my = rng.uniform(-3.0, h + 2.0, (12, 16)).astype(np.float32)
    image = rng.integers(0, 255, (h, w), dtype=np.uint8)
    _, mask = _warp(image, (mx, my), (w, h))
    t = MAP_TOLERANCE
    inside = (mx >= -t) & (my >= -t) & (mx <= w - 1 + t) & (my <= h - 1 + t)
    np.testing.assert_array_equal(mask, inside)


@hyp_settings(max_examples=examples(30))
@given(lo=st.floats(-500.0, 500.0), span=st.floats(0.0, 800.0), forced=st.integers(1, 1000))
def test_a_forced_canvas_is_centred_on_the_warped_extent(lo, span, forced):
    hi = lo + span
    start, n = _axis_window(lo, hi, 0.0, 10_000, forced)
    assert n == forced
    assert abs(start + (forced - 1) / 2.0 - (lo + hi) / 2.0) <= 1e-9
