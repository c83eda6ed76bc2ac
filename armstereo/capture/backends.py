"""Build arm and camera backends from their CLI names (``mock``, ``ur``, ``opencv:<dev>``).

Vendor SDKs load only inside the backend that needs them, so the mock path imports no ur_rtde.
"""

from __future__ import annotations

import numpy as np

from armstereo.devices import Arm, Camera
from armstereo.errors import ConfigError, IKError
from armstereo.kinematics import ArmModel, ready_configuration

ARM_KINDS = ("mock", "ur")
MOCK_CAMERA_HEIGHT_M = 0.55  # camera above the table (z = 0 in base) at the mock start pose


def build_arm(kind: str, model: ArmModel, *, host: str | None = None, realtime: bool = False,
              joint_noise: float = 0.0, faults=None, q0: np.ndarray | None = None,
              seed: int = 0) -> Arm:
    """An unconnected arm backend of ``kind``; the caller connects it (context manager)."""
    if kind == "mock":
        from drivers.mock.arm import MockArm

        start = mock_start_configuration(model) if q0 is None else q0
        return MockArm(model, start, realtime=realtime, joint_noise=joint_noise, seed=seed,
                       faults=faults)
    if kind == "ur":
        if not host:
            raise ConfigError("--arm ur needs --host IP (the controller's address)")
        from drivers.ur.arm import URArm

        return URArm(host, model)
    raise ConfigError(f"unknown arm {kind!r}; choose one of: {', '.join(ARM_KINDS)}")


def build_camera(spec: str, model: ArmModel, arm: Arm, *, faults=None, noise: float = 0.0,
                 scene=None, seed: int = 0) -> Camera:
    """An unconnected camera from ``mock`` or ``opencv:<index-or-path>``.

    The mock camera renders from the pose the kinematics give for the arm's actual joints, so it
    pairs with any arm backend.
    """
    if spec == "mock":
        from drivers.mock.camera import MockCamera

        return MockCamera(model.mount.intrinsics, lambda: model.camera_pose(arm.joint_positions()),
                          scene=scene, clock=arm.clock, noise_sigma=noise, seed=seed,
                          faults=faults)
    if spec.startswith("opencv:") and len(spec) > len("opencv:"):
        from drivers.opencv.camera import OpenCVCamera

        dev = spec.split(":", 1)[1]
        return OpenCVCamera(int(dev) if dev.isdigit() else dev, model.mount.intrinsics,
                            clock=arm.clock)
    raise ConfigError(f"unknown camera {spec!r}; use 'mock' or 'opencv:<index or path>'")


def mock_start_configuration(model: ArmModel, height: float = MOCK_CAMERA_HEIGHT_M,
                             center_xy: tuple[float, float] | None = None) -> np.ndarray:
    """Joints that put the camera ``height`` m above the mock scene's centre, looking down.

    The camera keeps the orientation it has at the model's ready configuration (which looks
    straight down) and is translated over the scene centre; IK is seeded from that pose.
    """
    from drivers.mock.scene import SCENE_CENTER

    cx, cy = SCENE_CENTER[:2] if center_xy is None else center_xy
    q_ready = ready_configuration(model.name)
    T_cam = model.camera_pose(q_ready)
    T_cam[:3, 3] = (cx, cy, height)
    try:
        return model.ik(model.flange_pose_for_camera(T_cam), q_ready, margin=0.1)
    except IKError as err:
        raise ConfigError(f"{model.name} cannot place the camera {height} m above the mock "
                          f"scene at ({cx:.2f}, {cy:.2f}) (the scene is laid out for arms with "
                          f"0.85 m reach or more, e.g. ur5e): {err}") from None


SWEEP_CAMERA_HEIGHT_M = 0.35


def sweep_start_configuration(model: ArmModel, height: float = SWEEP_CAMERA_HEIGHT_M) -> np.ndarray:
    """Joints that put the camera ``height`` m above the table over the mock scene centre,
    looking horizontally away from the robot (camera y down), for the baseline sweep."""
    from drivers.mock.scene import SCENE_CENTER

    cx, cy = SCENE_CENTER[:2]
    z_c = np.array([cx, cy, 0.0]) / np.hypot(cx, cy)  # look away from the base axis
    y_c = np.array([0.0, 0.0, -1.0])
    T_cam = np.eye(4)
    T_cam[:3, :3] = np.column_stack([np.cross(y_c, z_c), y_c, z_c])
    T_cam[:3, 3] = (cx, cy, height)
    seed = ready_configuration(model.name)
    try:
        return model.ik(model.flange_pose_for_camera(T_cam), seed, margin=0.1, max_iter=1000)
    except IKError as err:
        raise ConfigError(f"{model.name} cannot point the camera horizontally {height} m above "
                          f"the mock scene: {err}") from None
