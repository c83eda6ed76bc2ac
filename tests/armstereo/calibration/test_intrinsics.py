"""Intrinsics from board views and board poses from PnP."""

from __future__ import annotations

import math

import numpy as np
import pytest

from armstereo.calibration.board import parse_board
from armstereo.calibration.intrinsics import (
    board_pose,
    calibrate_intrinsics,
    check_distortion_model,
    reprojection_rms,
)
from armstereo.calibration.poses import pose_difference, rotmat
from armstereo.calibration.synthetic import observe_board
from armstereo.camera_model import Intrinsics
from armstereo.errors import ConfigError
from armstereo.transforms import make_T

TRUE = Intrinsics(640, 480, np.array([[612.0, 0.0, 322.0], [0.0, 612.6, 236.0], [0.0, 0.0, 1.0]]),
                  np.array([-0.08, 0.05, 0.0, 0.0, 0.0]))
BOARD = parse_board("chessboard:17x12:0.016")
NOISE_PX = 0.3


def _poses(n: int) -> list[np.ndarray]:
    """Board poses tilted up to ~35 deg about varying axes, rolled, at 0.4-0.5 m."""
    out = []
    for k in range(n):
        a = math.radians(137.5 * k)
        tilt = math.radians(35.0 * ((k * 0.618) % 1.0)) if k else 0.0
        R = rotmat(np.array([math.cos(a), math.sin(a), 0.0]) * tilt) @ rotmat(
            [0.0, 0.0, math.radians(60.0 * (2 * ((k * 0.755) % 1.0) - 1))])
        out.append(make_T(R, [0.0, 0.0, 0.4 + 0.05 * (k % 3)] - R @ BOARD.center))
    return out


def _detections(seed: int, n: int = 15):
    rng = np.random.default_rng(seed)
    return [d for d in (observe_board(BOARD, TRUE, T, NOISE_PX, rng) for T in _poses(n))
            if d is not None]


def test_intrinsics_recovered_within_half_a_percent_with_honest_rms():
    dets = _detections(0)
    assert len(dets) >= 12
    fit = calibrate_intrinsics(dets, (640, 480))
    assert fit.intrinsics.fx == pytest.approx(TRUE.fx, rel=0.005)
    assert fit.intrinsics.fy == pytest.approx(TRUE.fy, rel=0.005)
    assert abs(fit.intrinsics.cx - TRUE.cx) < 3 and abs(fit.intrinsics.cy - TRUE.cy) < 3
    # RMS of Euclidean errors for Gaussian noise per coordinate: about sqrt(2) * sigma
    assert fit.rms_px == pytest.approx(NOISE_PX * math.sqrt(2), rel=0.15)
    assert fit.per_view_rms_px.shape == (len(dets),)
    assert fit.intrinsics.dist[2:].tolist() == [0.0, 0.0, 0.0]  # radial-only default
    assert fit.std.shape == (4,) and np.all(fit.std > 0)


def test_board_pose_is_exact_on_exact_corners():
    T = _poses(4)[3]
    det = observe_board(BOARD, TRUE, T, 0.0, np.random.default_rng(0))
    dt, dr = pose_difference(board_pose(det, TRUE), T)
    assert dt < 1e-9 and dr < 1e-7
    assert reprojection_rms(det, TRUE, T) < 1e-9


def test_distortion_model_names_are_checked():
    assert check_distortion_model("k1k2p1p2k3") == "k1k2p1p2k3"
    with pytest.raises(ConfigError, match="distortion model"):
        check_distortion_model("fisheye")
    with pytest.raises(ConfigError, match="at least 3"):
        calibrate_intrinsics(_detections(1)[:2], (640, 480))
