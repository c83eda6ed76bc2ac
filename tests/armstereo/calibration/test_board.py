"""Board specs, corner coordinates, detection in rendered views, rendering."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from armstereo.calibration.board import (
    CHARUCO,
    CHESSBOARD,
    Detection,
    detect_board,
    parse_board,
    render_board_view,
)
from armstereo.calibration.poses import rotmat
from armstereo.camera_model import Intrinsics
from armstereo.errors import ConfigError
from armstereo.transforms import make_T

K = np.array([[610.0, 0.0, 321.0], [0.0, 611.0, 238.0], [0.0, 0.0, 1.0]])
INTR = Intrinsics(640, 480, K, np.array([-0.08, 0.05, 0.0, 0.0, 0.0]))
MAX_CORNER_ERROR_PX = 0.2  # detected vs exact projection, rendered with anti-aliasing


def test_chessboard_spec_fields_and_round_trip():
    b = parse_board("chessboard:10x7:0.025")
    assert (b.kind, b.cols, b.rows, b.square_m) == (CHESSBOARD, 10, 7, 0.025)
    assert b.inner_size == (9, 6) and b.corner_count == 54
    assert parse_board(b.spec) == b
    assert "54 inner corners" in b.describe()


def test_charuco_spec_default_and_explicit_dictionary():
    b = parse_board("charuco:7x5:0.04:0.03")
    assert (b.kind, b.marker_m, b.dictionary) == (CHARUCO, 0.03, "DICT_5X5_100")
    b2 = parse_board("CHARUCO:7x5:0.04:0.03:4x4_50")
    assert b2.dictionary == "DICT_4X4_50"
    assert parse_board(b2.spec) == b2


def test_object_points_are_row_major_from_the_first_inner_corner():
    b = parse_board("chessboard:10x7:0.02")
    p = b.object_points
    assert p.shape == (54, 3) and np.all(p[:, 2] == 0)
    np.testing.assert_allclose(p[0], [0.02, 0.02, 0.0])
    np.testing.assert_allclose(p[1], [0.04, 0.02, 0.0])
    np.testing.assert_allclose(p[9], [0.02, 0.04, 0.0])  # next row
    # ChArUco boards number their corners the same way as OpenCV does
    c = parse_board("charuco:10x7:0.02:0.015")
    np.testing.assert_allclose(c.object_points, c._cv_board.getChessboardCorners())


@pytest.mark.parametrize("spec, words", [
    ("", "must start with"),
    ("chess:10x7:0.02", "must start with"),
    ("chessboard:10x7", "must look like"),
    ("chessboard:10by7:0.02", "COLSxROWS"),
    ("chessboard:10x8:0.02", "180 degrees"),
    ("chessboard:9x7:0.02", "180 degrees"),
    ("chessboard:10x7:25", "did you mean 0.025"),
    ("chessboard:10x7:-1", "positive length"),
    ("chessboard:2x3:0.02", "squares per side"),
    ("charuco:7x5:0.03:0.04", "smaller than the square"),
    ("charuco:7x5:0.03:0.02:DICT_NOPE", "unknown ArUco dictionary"),
    ("charuco:20x20:0.01:0.007:DICT_4X4_50", "larger dictionary"),
])
def test_bad_specs_say_what_is_wrong_on_one_line(spec, words):
    with pytest.raises(ConfigError) as info:
        parse_board(spec)
    assert words in str(info.value) and "\n" not in str(info.value)


def _view(board, yaw_deg, tilt_deg=0.0, distance=0.42, offset=(0.0, 0.0)):
    """T_camera_board with the board centre on (near) the optical axis, turned and tilted."""
    R = rotmat([math.radians(tilt_deg), 0.0, 0.0]) @ rotmat([0.0, 0.0, math.radians(yaw_deg)])
    t = np.array([offset[0], offset[1], distance]) - R @ board.center
    return make_T(R, t)


def _truth(board, T, ids):
    rvec = cv2.Rodrigues(T[:3, :3])[0]
    uv, _ = cv2.projectPoints(board.object_points[ids], rvec, T[:3, 3], INTR.K, INTR.dist)
    return uv.reshape(-1, 2)


@pytest.mark.parametrize("yaw, tilt", [(0, 0), (90, 0), (180, 25), (270, -30), (35, 40)])
def test_chessboard_corners_come_back_in_board_order_whatever_the_view(yaw, tilt):
    board = parse_board("chessboard:10x7:0.025")
    T = _view(board, yaw, tilt)
    img = render_board_view(board, INTR, T, noise_sigma=1.0, seed=yaw, supersample=2)
    det = detect_board(img, board)
    assert det is not None and len(det) == board.corner_count
    err = np.linalg.norm(det.image_points - _truth(board, T, det.ids), axis=1)
    assert err.max() < MAX_CORNER_ERROR_PX


def test_charuco_detects_the_visible_part_of_a_board():
    board = parse_board("charuco:10x7:0.03:0.022")
    T = _view(board, 20, 10, distance=0.35, offset=(0.12, 0.0))  # right part out of the image
    img = render_board_view(board, INTR, T, supersample=2)
    det = detect_board(img, board)
    assert det is not None and 10 <= len(det) < board.corner_count
    err = np.linalg.norm(det.image_points - _truth(board, T, det.ids), axis=1)
    assert err.max() < MAX_CORNER_ERROR_PX
    np.testing.assert_array_equal(det.object_points, board.object_points[det.ids])


def test_no_board_gives_none_and_colour_images_work():
    board = parse_board("chessboard:10x7:0.025")
    assert detect_board(np.full((480, 640), 128, np.uint8), board) is None
    img = render_board_view(board, INTR, _view(board, 0), supersample=2)
    det = detect_board(cv2.cvtColor(img, cv2.COLOR_GRAY2BGR), board)
    assert det is not None
    with pytest.raises(ConfigError):
        detect_board(img.astype(np.float32), board)


def test_spacing_is_the_pixel_distance_of_neighbouring_corners():
    board = parse_board("chessboard:10x7:0.025")
    obj = board.object_points
    det = Detection(np.arange(len(obj)), obj[:, :2] * 1000.0, obj)  # 1 mm = 1 px
    assert det.spacing_px == pytest.approx(25.0)


def test_reflectance_black_first_square_white_margin_nan_outside():
    board = parse_board("chessboard:10x7:0.025")
    v = board.reflectance(np.array([[0.01, 0.01], [0.035, 0.01], [-0.01, 0.05], [-1.0, 0.0]]))
    assert v[0] == 0.0 and v[1] == 1.0 and v[2] == 1.0 and math.isnan(v[3])
