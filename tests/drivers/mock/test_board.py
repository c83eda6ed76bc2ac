"""The calibration board in the mock world: where it lies, what it looks like, and that its
rendered corners are where the geometry says (no snapping to the pixel grid)."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from armstereo import backends
from armstereo.calibration.board import detect_board, parse_board
from armstereo.kinematics import ArmModel
from armstereo.transforms import invert
from drivers.mock import board as mock_board
from drivers.mock.scene import SCENE_CENTER, default_table_scene

BOARD = parse_board("chessboard:17x12:0.016")


@pytest.fixture(scope="module")
def ur5e() -> ArmModel:
    return ArmModel.load("ur5e", mount="default_wrist_camera")


def _render_start_view(model: ArmModel, board, *, edge_supersample: int | None = None,
                       seed: int = 0):
    """Image of the table start view with ``board`` on the table, and its true corners."""
    scene = mock_board.calibration_scene(board, default_table_scene(seed), seed)
    if edge_supersample is not None:
        scene.primitives[0].edge_supersample = edge_supersample
    T_cam = model.camera_pose(backends.mock_start_joints(model, "table"))
    intr = model.mount.intrinsics
    image, depth = scene.render(T_cam, intr, supersample=2)
    T_cb = invert(T_cam) @ mock_board.board_pose(board, seed)
    rvec = cv2.Rodrigues(np.ascontiguousarray(T_cb[:3, :3]))[0]
    uv, _ = cv2.projectPoints(board.object_points, rvec, T_cb[:3, 3], intr.K, intr.dist)
    return image, depth, uv.reshape(-1, 2)


def test_board_lies_flat_on_the_table_face_up_below_the_start_camera():
    T = mock_board.board_pose(BOARD, seed=3)
    centre = (T @ np.append(BOARD.center, 1.0))[:3]
    assert abs(centre[2] - mock_board.BOARD_THICKNESS_M) < 1e-12
    assert np.hypot(centre[0] - SCENE_CENTER[0], centre[1] - SCENE_CENTER[1]) < 0.015
    np.testing.assert_allclose(T[:3, 2], [0.0, 0.0, -1.0], atol=1e-12)  # z into the table
    assert np.isclose(np.linalg.det(T[:3, :3]), 1.0)
    assert not np.allclose(T, mock_board.board_pose(BOARD, seed=4))  # seeded


def test_scene_is_the_cleared_table_with_the_board():
    scene = mock_board.calibration_scene(BOARD, default_table_scene(0))
    assert [p.name for p in scene.primitives] == ["calibration_board", "table", "floor"]
    assert scene.support == "table"
    truth = scene.truth()
    assert any(p.name == "calibration_board" for p in truth.primitives)


def test_texture_is_ink_on_paper_with_a_white_margin():
    rect = mock_board.board_primitive(BOARD, np.eye(4))
    x0, y0, x1, y1 = mock_board.sheet_extent(BOARD)
    cx, cy = (x0 + x1) / 2, (y0 + y1) / 2
    s = BOARD.square_m
    # board-frame points: top-left square (black), its right neighbour (white), the margin
    pts = np.array([[0.5 * s, 0.5 * s], [1.5 * s, 0.5 * s], [x0 + 0.001, y0 + 0.001]])
    grey = rect.texture.sample(pts[:, 0] - cx, pts[:, 1] - cy)
    assert grey.shape == (3, 3)
    np.testing.assert_allclose(grey[0], [mock_board.INK_GREY, mock_board.PAPER_GREY,
                                         mock_board.PAPER_GREY])


def test_rendered_corners_are_where_the_geometry_puts_them(ur5e):
    image, depth, truth = _render_start_view(ur5e, BOARD)
    det = detect_board(image, BOARD)
    assert det is not None and len(det) == BOARD.corner_count
    err = det.image_points - truth
    assert np.sqrt(np.mean(err**2)) < 0.08  # px, per coordinate
    assert np.all(np.abs(err.mean(axis=0)) < 0.02)  # no bias
    # the board is 0.55 m below the start camera, minus its thickness
    centre_px = np.round(truth.mean(axis=0)).astype(int)
    assert abs(depth[centre_px[1], centre_px[0]] - 0.547) < 0.003


def test_one_ray_per_pixel_snaps_edges_to_the_grid(ur5e):
    """Why the board's edges are supersampled: with one ray per pixel the corners are off by
    several times more."""
    sharp, _, truth = _render_start_view(ur5e, BOARD, edge_supersample=1)
    smooth, _, _ = _render_start_view(ur5e, BOARD)
    rms = [np.sqrt(np.mean((detect_board(img, BOARD).image_points - truth) ** 2))
           for img in (sharp, smooth)]
    assert rms[0] > 2.5 * rms[1]


def test_mock_camera_config_lays_the_board(ur5e):
    arm_cfg = backends.arm_config("mock")
    cam_cfg = backends.camera_config("mock", board=BOARD)
    with backends.build_arm("mock", arm_cfg, ur5e) as arm, \
            backends.build_camera("mock", cam_cfg, ur5e, arm) as camera:
        frame = camera.grab()
    assert camera.scene.primitives[0].name == "calibration_board"
    assert detect_board(frame.image, BOARD) is not None
