"""Shared fixtures for the calibration tests: the UR5e with the default wrist camera."""

from __future__ import annotations

import pytest

from armstereo.robot.arm_model import ArmModel

# The board most tests calibrate with: 16x11 = 176 inner corners of 16 mm, 27 x 19 cm.
BOARD_SPEC = "chessboard:17x12:0.016"


@pytest.fixture(scope="session")
def ur5e() -> ArmModel:
    """UR5e kinematics with the bundled (nominal) wrist camera mount."""
    return ArmModel.load("ur5e", mount="default_wrist_camera")
