"""Arm poses the mock scenes are laid out for (controller ``base`` frame, metres, radians).

The table scene is centred at :data:`drivers.mock.scene.SCENE_CENTER`; ``table`` puts the camera
above that point looking straight down, ``horizontal`` puts it above the table looking across,
away from the robot (the baseline sweep's view of its planar targets).
"""

from __future__ import annotations

import numpy as np

from armstereo.errors import ConfigError, IKError
from armstereo.kinematics import ArmModel, ready_configuration
from drivers.mock.scene import SCENE_CENTER

TABLE_CAMERA_HEIGHT_M = 0.55  # camera above the table (z = 0 in base) at the table start pose
HORIZONTAL_CAMERA_HEIGHT_M = 0.35
LAYOUTS = ("table", "horizontal")
LIMIT_MARGIN_RAD = 0.1  # start poses keep this far from every joint limit


def start_joints(model: ArmModel, layout: str = "table") -> np.ndarray:
    """Joints for the mock ``layout`` (see module doc); ConfigError when the arm cannot."""
    if layout == "table":
        return table_start(model)
    if layout == "horizontal":
        return horizontal_start(model)
    raise ConfigError(f"unknown mock layout {layout!r}; choose one of: {', '.join(LAYOUTS)}")


def table_start(model: ArmModel, height: float = TABLE_CAMERA_HEIGHT_M,
                center_xy: tuple[float, float] | None = None) -> np.ndarray:
    """Joints that put the camera ``height`` m above the scene centre, looking down.

    The camera keeps the orientation it has at the model's ready configuration (which looks
    straight down) and is translated over the scene centre; IK is seeded from that pose.
    """
    cx, cy = SCENE_CENTER[:2] if center_xy is None else center_xy
    q_ready = ready_configuration(model.name)
    T_cam = model.camera_pose(q_ready)
    T_cam[:3, 3] = (cx, cy, height)
    try:
        return model.ik(model.flange_pose_for_camera(T_cam), q_ready, margin=LIMIT_MARGIN_RAD)
    except IKError as err:
        raise ConfigError(f"{model.name} cannot place the camera {height} m above the mock "
                          f"scene at ({cx:.2f}, {cy:.2f}) (the scene is laid out for arms with "
                          f"0.85 m reach or more, e.g. ur5e): {err}") from None


def horizontal_start(model: ArmModel, height: float = HORIZONTAL_CAMERA_HEIGHT_M) -> np.ndarray:
    """Joints that put the camera ``height`` m above the table over the scene centre, looking
    horizontally away from the robot (camera y down)."""
    cx, cy = SCENE_CENTER[:2]
    z_c = np.array([cx, cy, 0.0]) / np.hypot(cx, cy)  # look away from the base axis
    y_c = np.array([0.0, 0.0, -1.0])
    T_cam = np.eye(4)
    T_cam[:3, :3] = np.column_stack([np.cross(y_c, z_c), y_c, z_c])
    T_cam[:3, 3] = (cx, cy, height)
    seed = ready_configuration(model.name)
    try:
        return model.ik(model.flange_pose_for_camera(T_cam), seed, margin=LIMIT_MARGIN_RAD,
                        max_iter=1000)
    except IKError as err:
        raise ConfigError(f"{model.name} cannot point the camera horizontally {height} m above "
                          f"the mock scene: {err}") from None
