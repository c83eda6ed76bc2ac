"""Corner views: the board pushed into each image corner, every planner check passed."""

from __future__ import annotations

import numpy as np

from armstereo.calibration.board import parse_board
from armstereo.calibration.coverage import CORNERS, _outline_px, coverage_views
from armstereo.calibration.views import ViewPlanSettings, plan_calibration_views
from armstereo.transforms import invert, make_T

from .conftest import BOARD_SPEC


def test_corner_views_put_the_board_into_each_corner(ur5e):
    board = parse_board(BOARD_SPEC)
    q0 = np.array([-0.009, -1.800, 1.507, -1.278, -1.571, -0.009])  # the mock's table start
    T_cb = make_T(np.eye(3), [0.0, 0.0, 0.55]) @ make_T(np.eye(3), -board.center)
    plan = plan_calibration_views(ur5e, q0, board, T_camera_board_start=T_cb,
                                  settings=ViewPlanSettings(n_views=6))
    views, skipped = coverage_views(ur5e, q0, plan, board, 4)
    assert len(views) == 4 and skipped == []
    intr = ur5e.mount.intrinsics
    for view, (sx, sy) in zip(views, CORNERS, strict=True):
        uv = _outline_px(ur5e, view.T_base_camera, plan.T_base_board, board)
        inside = (uv[:, 0] > 0) & (uv[:, 0] < intr.width) & (uv[:, 1] > 0) & \
            (uv[:, 1] < intr.height)
        assert inside.all()
        # the squares' far corner comes within 60 px of the image corner it was sent to (the
    # planner keeps 15 px of margin; the fit stops where the board would leave the image)
        corner = np.array([(intr.width - 1) * (sx > 0), (intr.height - 1) * (sy > 0)])
        assert np.min(np.linalg.norm(uv - corner, axis=1)) < 60
        centre = (invert(view.T_base_camera) @ plan.T_base_board
                  @ np.append(board.center, 1.0))[:3]
        assert np.sign(centre[0]) == sx and np.sign(centre[1]) == sy
        assert ur5e.within_limits(view.q, 0.05)
