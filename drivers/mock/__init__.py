"""Mock backends, the embedded default: a simulated UR arm, a ray-casting camera, its scenes and
injectable faults. Deterministic; they run on a simulated clock unless asked for real time.

Typical wiring (the camera renders from forward kinematics of the arm's actual joints)::

    arm = MockArm(model, q0, faults=plan)
    cam = MockCamera(model.mount.intrinsics, lambda: model.camera_pose(arm.joint_positions()),
                     clock=arm.clock, faults=plan)
"""

from drivers.mock.arm import MockArm
from drivers.mock.camera import MockCamera
from drivers.mock.faults import FAULT_NAMES, FaultPlan
from drivers.mock.scene import (
    SCENE_CENTER,
    PlanarTarget,
    Scene,
    TargetScene,
    default_table_scene,
    planar_target_scene,
)

__all__ = [
    "FAULT_NAMES",
    "SCENE_CENTER",
    "FaultPlan",
    "MockArm",
    "MockCamera",
    "PlanarTarget",
    "Scene",
    "TargetScene",
    "default_table_scene",
    "planar_target_scene",
]
