"""Board corners under a glare are found in the image and left out."""

from __future__ import annotations

import numpy as np

from armstereo.calibration.board import detect_board, parse_board, render_board_view
from armstereo.calibration.glare import ink_paper_ratio, without_glare
from armstereo.camera_model import Intrinsics
from armstereo.transforms import make_T, rot_x, rot_z

BOARD = parse_board("chessboard:10x7:0.03")
INTR = Intrinsics(640, 480, [[600.0, 0.0, 322.0], [0.0, 600.0, 237.0], [0.0, 0.0, 1.0]],
                  [-0.08, 0.04, 0.0, 0.0, 0.0])
SPOT = (300.0, 250.0)  # glare centre (px)


def view(glare: float, vignetting: bool = True) -> np.ndarray:
    """The board 0.7 m away, printed ink 25 / paper 235, darker towards the image corners,
    with a highlight of ``glare`` grey levels at SPOT."""
    R = rot_z(0.1) @ rot_x(0.2)
    T = make_T(R, np.array([0.0, 0.0, 0.7]) - R @ BOARD.center)
    img = render_board_view(BOARD, INTR, T, background=60, supersample=2).astype(float)
    img = 25 + (235 - 25) * img / 255.0
    v, u = np.mgrid[0:480, 0:640]
    if vignetting:
        r2 = ((u - 322) ** 2 + (v - 237) ** 2) / (400.0 ** 2)
        img *= 1.0 - 0.25 * r2
    img += glare * np.exp(-((u - SPOT[0]) ** 2 + (v - SPOT[1]) ** 2) / (2 * 30.0 ** 2))
    img += np.random.default_rng(2).normal(0, 1.5, img.shape)
    return np.clip(np.rint(img), 0, 255).astype(np.uint8)


def test_a_clean_view_keeps_every_corner_despite_vignetting():
    img = view(0.0)
    det = detect_board(img, BOARD)
    kept, screen = without_glare(img, det, BOARD)
    assert screen.left_out == 0 and kept is det
    ratio = ink_paper_ratio(img, det, BOARD)
    assert np.nanmax(ratio) - np.nanmin(ratio) < 0.02  # the print's ratio is one number


def test_corners_in_the_glare_are_left_out_and_only_those():
    img = view(120.0)
    det = detect_board(img, BOARD)
    kept, screen = without_glare(img, det, BOARD)
    assert 3 <= screen.left_out < 0.5 * len(det)
    gone = np.setdiff1d(det.ids, kept.ids)
    d_gone = np.linalg.norm(det.image_points[gone] - SPOT, axis=1)
    d_kept = np.linalg.norm(kept.image_points - SPOT, axis=1)
    assert d_gone.max() < 90.0 and d_kept.min() > 30.0  # the spot's corners, nothing far off
    # what is kept is consistent: ids, image and board points of the same corners
    np.testing.assert_array_equal(kept.object_points, det.object_points[kept.ids])
    np.testing.assert_array_equal(kept.image_points, det.image_points[kept.ids])


def test_a_view_without_a_board_passes_through():
    assert without_glare(view(0.0), None, BOARD) == (None, None)
