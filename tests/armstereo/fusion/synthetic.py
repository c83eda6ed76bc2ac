"""Exact depth maps of the mock table scene for the fusion tests.

The mock scene's ray caster returns the exact z-depth of the ray through every pixel centre
(OpenCV convention, independent of the fusion code) and knows its exact geometry, so a fused
surface can be scored to the micrometre. A small camera keeps the tests fast.
"""

from __future__ import annotations

import math

import numpy as np

from armstereo.camera_model import Intrinsics
from armstereo.capture.scan_plan import look_at_pose
from armstereo.fusion.tsdf import DepthFrame, Roi
from drivers.mock.scene import SCENE_CENTER, default_table_scene

SMALL = Intrinsics(320, 240, np.array([[300.0, 0.0, 159.5], [0.0, 300.0, 119.5],
                                       [0.0, 0.0, 1.0]]))
TARGET = np.array([SCENE_CENTER[0], SCENE_CENTER[1], 0.03])
ROI = Roi((SCENE_CENTER[0] - 0.2, SCENE_CENTER[1] - 0.2, -0.012),
          (SCENE_CENTER[0] + 0.2, SCENE_CENTER[1] + 0.2, 0.17))


def ring_frames(n: int = 8, *, elevation_deg: float = 55.0, radius: float = 0.45,
                intrinsics: Intrinsics = SMALL, cx_shift: float = 0.0, cy_shift: float = 0.0):
    """(frames, truth): exact depth maps from ``n`` views on a ring looking at the scene
    centre. ``cx_shift``/``cy_shift`` (px) move the principal point the fusion is told about,
    i.e. they simulate a wrong pixel-centre convention."""
    scene = default_table_scene(0, floor=False)
    frames = []
    for k in range(n):
        T = look_at_pose(TARGET, 2 * math.pi * k / n, math.radians(elevation_deg), radius)
        image, depth = scene.render(T, intrinsics, supersample=1)
        K = intrinsics.K.copy()
        K[0, 2] += cx_shift
        K[1, 2] += cy_shift
        frames.append(DepthFrame(depth, K, T, image, pair=k, label=f"view {k}"))
    return frames, scene.truth()


def small_model():
    """UR5e with the default mount's hand-eye but the SMALL camera (fast to render and match)."""
    from armstereo.mount import CameraMount
    from armstereo.robot.arm_model import ArmModel

    default = CameraMount.load(None)
    mount = CameraMount("small_test_camera", default.T_flange_camera, SMALL, default.source)
    return ArmModel.load("ur5e", mount=mount)


def record_small_scan(path, views: str = "ring:4", *, camera_noise: float = 1.0,
                      elevation_deg: float = 55.0, radius: float = 0.45, baseline: float = 0.06,
                      faults: tuple[str, ...] = ()):
    """A mock multi-view scan of the table scene with the SMALL camera into ``path``, recorded
    by the code ``armstereo scan`` runs; returns its ScanOutcome."""
    from armstereo import backends
    from armstereo.apps.scan import ScanRequest, backend_metadata, record_scan

    arm = backends.arm_config("mock", seed=1, faults=faults)
    camera = backends.camera_config("mock", noise=camera_noise, seed=1, faults=faults)
    request = ScanRequest(target=tuple(TARGET), views=views, radius=radius,
                          elevation_deg=elevation_deg, baseline=baseline)
    return record_scan(path, request, small_model(), arm_config=arm, camera_config=camera,
                       metadata=backend_metadata("mock", arm, "mock", camera), progress=None)
