"""The lens's fall-off from calibration views: the board's white paper as a flat field."""

from __future__ import annotations

import numpy as np
import pytest

from armstereo.calibration.board import parse_board, render_board_view
from armstereo.calibration.vignetting import estimate_vignetting, white_points
from armstereo.camera_model import Intrinsics
from armstereo.photometric.vignetting import Vignetting
from armstereo.transforms import make_T, rot_x, rot_z

BOARD = parse_board("chessboard:10x7:0.03")
INTR = Intrinsics(640, 480, [[600.0, 0.0, 322.0], [0.0, 600.0, 237.0], [0.0, 0.0, 1.0]],
                  [-0.08, 0.04, 0.0, 0.0, 0.0])
TRUE = Vignetting(640, 480, (322.0, 237.0), (-0.16, -0.09, 0.0))


def views(offsets):
    """Board views 0.9 m away, its centre seen at normalised offsets (x, y), a little tilted;
    each with its own exposure and the true fall-off, some with a glare spot."""
    rng = np.random.default_rng(5)
    images, poses = [], []
    for k, (x, y) in enumerate(offsets):
        R = rot_z(0.2 * k) @ rot_x(0.15 * (-1) ** k)
        T = make_T(R, np.array([x, y, 1.0]) * 0.9 - R @ BOARD.center)
        img = render_board_view(BOARD, INTR, T, background=60, supersample=2).astype(float)
        img = 25 + (235 - 25) * (img - 0) / 255.0  # ink and paper as printed
        img *= TRUE.gain_map() * rng.uniform(0.85, 1.05)
        if k % 3 == 1:  # a laminate's glare: a bright spot on some views
            v, u = np.mgrid[0:480, 0:640]
            img += 90 * np.exp(-((u - 200 - 30 * k) ** 2 + (v - 250) ** 2) / (2 * 25 ** 2))
        img += rng.normal(0, 1.5, img.shape)
        images.append(np.clip(np.rint(img), 0, 255).astype(np.uint8))
        poses.append(T)
    return images, poses


CORNERS = [(0.0, 0.0), (0.3, 0.2), (-0.3, -0.2), (0.3, -0.2), (-0.3, 0.2), (0.1, -0.05)]


def test_the_white_paper_keeps_clear_of_the_ink():
    pts = white_points(BOARD)
    r = BOARD.reflectance(pts[:, :2])
    assert len(pts) > 500 and np.all(r == 1.0)
    # a quarter of a square away from any black square
    for dx, dy in ((0.007, 0), (-0.007, 0), (0, 0.007), (0, -0.007)):
        near = BOARD.reflectance(pts[:, :2] + [dx, dy])
        assert np.all((near == 1.0) | np.isnan(near))


def test_the_fall_off_is_found_within_a_percent_at_the_corners():
    images, poses = views(CORNERS)
    fit = estimate_vignetting(images, BOARD, INTR, poses)
    assert fit.reaches_corners and fit.views == len(images)
    rel = fit.model.corner_gains() / TRUE.corner_gains() - 1.0
    assert np.abs(rel).max() < 0.01, rel
    assert fit.rms_rel < 0.03


def test_without_corner_views_the_fit_says_the_corners_are_extrapolated():
    images, poses = views([(0.0, 0.0), (0.05, 0.03), (-0.05, -0.02)])
    fit = estimate_vignetting(images, BOARD, INTR, poses)
    assert not fit.reaches_corners


def test_too_little_paper_gives_no_fit():
    images, poses = views([(0.0, 0.0)])
    blank = [np.zeros_like(images[0])]
    assert estimate_vignetting(blank, BOARD, INTR, poses) is None


@pytest.mark.parametrize("channels", [1, 3])
def test_grey_and_colour_views(channels):
    images, poses = views(CORNERS[:4])
    if channels == 3:
        images = [np.repeat(i[..., None], 3, axis=2) for i in images]
    fit = estimate_vignetting(images, BOARD, INTR, poses)
    assert fit is not None and fit.samples > 1000
