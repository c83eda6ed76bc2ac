"""MockCamera: frames rendered from the pose source, ground truth, noise, clock, faults."""

from __future__ import annotations

import numpy as np
import pytest

from armstereo.camera_model import Intrinsics
from armstereo.clock import SimClock
from armstereo.errors import CameraTimeout, ConfigError, NotConnected
from armstereo.transforms import make_T
from drivers.mock.camera import MockCamera
from drivers.mock.faults import FaultPlan
from drivers.mock.scene import SCENE_CENTER, default_table_scene

INTR = Intrinsics(160, 120, np.array([[150.0, 0, 79.5], [0, 150.0, 59.5], [0, 0, 1]]))
R_DOWN = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])
SCENE = default_table_scene()


class Pose:
    """A movable camera pose, standing in for FK of the arm's joints."""

    def __init__(self):
        self.T = make_T(R_DOWN, (*SCENE_CENTER, 0.55))
        self.calls = 0

    def __call__(self) -> np.ndarray:
        self.calls += 1
        return self.T.copy()


def camera(pose=None, **kw) -> MockCamera:
    cam = MockCamera(INTR, pose or Pose(), scene=SCENE, **kw)
    cam.connect()
    return cam


def test_grab_renders_from_the_pose_source_with_ground_truth():
    pose, clock = Pose(), SimClock(start_ns=1000)
    cam = camera(pose, clock=clock)
    frame = cam.grab()
    assert frame.image.shape == (120, 160, 3) and frame.image.dtype == np.uint8
    assert frame.depth.shape == (120, 160) and frame.depth.dtype == np.float32
    assert pose.calls == 1
    expected, depth = SCENE.render(pose.T, INTR)
    assert np.array_equal(frame.image, expected) and np.array_equal(frame.depth, depth)
    assert cam.ground_truth_depth is frame.depth
    assert frame.timestamp_ns == 1000 + round(1e9 / 30)  # stamped at the next exposure
    pose.T = pose.T @ make_T(np.eye(3), (0.05, 0.0, 0.0))
    moved = cam.grab()
    assert not np.array_equal(moved.image, frame.image)
    assert moved.timestamp_ns > frame.timestamp_ns


def test_sensor_noise_is_seeded_and_has_the_asked_sigma():
    clean = camera().grab().image.astype(float)
    a = camera(noise_sigma=4.0, seed=7).grab().image.astype(float)
    b = camera(noise_sigma=4.0, seed=7).grab().image.astype(float)
    c = camera(noise_sigma=4.0, seed=8).grab().image.astype(float)
    assert np.array_equal(a, b) and not np.array_equal(a, c)
    inside = (clean > 20) & (clean < 235)  # away from clipping
    assert np.std((a - clean)[inside]) == pytest.approx(4.0, rel=0.1)


def test_camera_timeout_fault_hits_the_named_grab_only():
    clock = SimClock(start_ns=0)
    cam = camera(clock=clock, faults=FaultPlan.parse(["camera-timeout"]))  # default: grab 2
    cam.grab()
    t0 = clock.now_ns()
    with pytest.raises(CameraTimeout, match="mock camera.*grab 2"):
        cam.grab(timeout=1.5)
    assert clock.now_ns() - t0 == 1_500_000_000  # the caller waited its whole timeout
    assert cam.grab().image.shape == (120, 160, 3)  # grab 3 works again
    at_one = camera(faults=FaultPlan.parse(["camera-timeout@1", "disconnect@1"]))
    with pytest.raises(CameraTimeout):
        at_one.grab()


def test_connection_life_cycle_and_validation():
    cam = MockCamera(INTR, Pose(), scene=SCENE)
    with pytest.raises(NotConnected, match="not connected"):
        cam.grab()
    with cam:
        assert cam.is_connected and cam.intrinsics is INTR
        with pytest.raises(NotConnected, match="already connected"):
            cam.connect()
        with pytest.raises(ConfigError):
            cam.grab(timeout=0)
    assert not cam.is_connected
    cam.close()  # twice is fine
    assert cam.ground_truth_depth is None
    with pytest.raises(ConfigError):
        MockCamera(INTR, Pose(), noise_sigma=-1)
    with pytest.raises(ConfigError):
        MockCamera(INTR, "not callable")
    with pytest.raises(ConfigError):
        MockCamera(INTR.K, Pose())
