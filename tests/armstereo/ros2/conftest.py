"""Shared ROS 2 fixtures: the sample recording exported, and a bag recorded the way a UR driver
and a camera driver would (tests/support/ros2_bags.py), with the mock scene's images."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from armstereo import backends
from armstereo.camera_model import Intrinsics
from armstereo.cli.main import main
from armstereo.kinematics import ArmModel
from armstereo.mount import CameraMount
from armstereo.ros2.export import export_recording
from tests.support import SAMPLE_RECORDING
from tests.support.ros2_bags import build_driver_bag

BASELINE = 0.05
INTRINSICS = Intrinsics(320, 240, [[300.0, 0.0, 159.5], [0.0, 300.0, 119.5], [0.0, 0.0, 1.0]],
                        np.zeros(5))
_COARSE = Intrinsics(80, 60, [[75.0, 0.0, 39.5], [0.0, 75.0, 29.5], [0.0, 0.0, 1.0]],
                     np.zeros(5))


def run(capsys, *argv) -> tuple[int, str, list[str]]:
    """The CLI's exit code, stdout and stderr lines."""
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, [line for line in err.splitlines() if line.strip()]


@pytest.fixture(scope="session")
def sample_bag(tmp_path_factory):
    """recordings/sample.mcap exported (Humble)."""
    out = tmp_path_factory.mktemp("sample") / "sample_bag"
    export_recording(SAMPLE_RECORDING, out)
    return out


@pytest.fixture(scope="session")
def arm() -> ArmModel:
    return ArmModel.load("ur5e", mount=CameraMount.load(None))


def shifted(model: ArmModel, q: np.ndarray, dx: float, dy: float) -> np.ndarray:
    """Joints that move the camera by (dx, dy) along its own x and y (m)."""
    T = model.camera_pose(q)
    T[:3, 3] += T[:3, :3] @ np.array([dx, dy, 0.0])
    return model.ik(model.flange_pose_for_camera(T), q)


@pytest.fixture(scope="session")
def table_scene():
    return backends.mock_table_scene(0)


@pytest.fixture(scope="session")
def driver_bag(tmp_path_factory, arm, table_scene):
    """Four rests: two stereo pairs BASELINE apart along camera x, the second 4 cm over;
    TF and joint states at 500 Hz, images at 30 Hz."""
    q0 = backends.mock_start_joints(arm, "table")
    q2 = shifted(arm, q0, 0.0, 0.04)
    rests = [q0, shifted(arm, q0, BASELINE, 0.0), q2, shifted(arm, q2, BASELINE, 0.0)]

    def render(T, intr, rest):
        if rest is not None:
            return table_scene.render(T, intr)[0]
        coarse = table_scene.render(T, _COARSE, supersample=1)[0]  # moving: blurred anyway
        return cv2.resize(coarse, intr.size)

    path = tmp_path_factory.mktemp("driver") / "driver.mcap"
    return build_driver_bag(path, arm, rests, INTRINSICS, render)
