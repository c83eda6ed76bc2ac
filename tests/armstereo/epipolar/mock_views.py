"""Mock views whose TRUE camera differs from the recorded one (test helper).

The mock camera renders the table scene from ``T_base_camera_recorded @ D``: the camera sits on
the flange with a hand-eye transform off by ``D = T_camrecorded_camtrue``, while poses are
recorded with the nominal mount, as a wrong mount file or a slipped bracket would give.
"""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path

import numpy as np

from armstereo.clock import SimClock
from armstereo.mount import CameraMount
from armstereo.recording import RecordingWriter
from armstereo.robot.arm_model import ArmModel
from armstereo.transforms import invert, make_T, rot_x, rot_y, rot_z
from drivers.mock.camera import MockCamera
from drivers.mock.scene import default_table_scene
from drivers.mock.start_poses import table_start as mock_start_configuration

CAMERA_NOISE = 1.0  # grey levels, as in the demo
EXACT = make_T(np.eye(3), [0, 0, 0])
LATERAL = make_T(np.eye(3), [0.08, 0.0, 0.0])  # camera-frame motion of the second view
TILTED = make_T(rot_x(np.radians(20.0)), [0.08, 0.0, 0.0])  # ... with the wrist tilted 20 deg
ROLL_1DEG = make_T(rot_z(np.radians(1.0)), [0, 0, 0])
YAW_1DEG = make_T(rot_y(np.radians(1.0)), [0, 0, 0])
FORWARD_5MM = make_T(np.eye(3), [0.0, 0.0, 0.005])


@lru_cache(maxsize=1)
def model() -> ArmModel:
    return ArmModel.load("ur5e", mount=CameraMount.load(None))


def start_pose() -> np.ndarray:
    """Recorded camera pose of the first view (``base``, m): the mock start pose."""
    m = model()
    return m.camera_pose(mock_start_configuration(m))


def _camera(D: np.ndarray, seed: int) -> tuple[MockCamera, dict]:
    state = {"T": start_pose()}
    cam = MockCamera(model().mount.intrinsics, lambda: state["T"] @ D,
                     scene=default_table_scene(0), clock=SimClock(), noise_sigma=CAMERA_NOISE,
                     seed=seed)
    return cam, state


def render_pair(T_cam1_cam2: np.ndarray, D: np.ndarray = EXACT, seed: int = 0):
    """``(image1, image2, intrinsics, T_base_cam1, T_base_cam2)`` with RECORDED poses."""
    cam, state = _camera(D, seed)
    T1 = start_pose()
    T2 = T1 @ T_cam1_cam2
    with cam:
        state["T"] = T1
        im1 = cam.grab().image
        state["T"] = T2
        im2 = cam.grab().image
    return im1, im2, cam.intrinsics, T1, T2


def record_pair(path: Path, T_cam1_cam2: np.ndarray, D: np.ndarray = EXACT) -> Path:
    """A one-pair recording (view 0 at the start pose, view 1 moved by ``T_cam1_cam2``) whose
    /tf holds the nominal mount while the images come from the offset camera."""
    m = model()
    T_fc = m.mount.T_flange_camera
    q0 = mock_start_configuration(m)
    cam, state = _camera(D, seed=0)
    poses = [start_pose(), start_pose() @ T_cam1_cam2]
    with cam, RecordingWriter(path, metadata={"robot": m.name, "camera": "mock",
                                              "source": "tests: offset hand-eye"}) as w:
        w.write_calibration(cam.intrinsics, cam.clock.now_ns())
        q = q0
        for k, T in enumerate(poses):
            T_base_flange = T @ invert(T_fc)
            q = m.ik(T_base_flange, q)
            state["T"] = m.camera_pose(q)
            w.write_view(k, cam.grab(), q, m.joint_names, m.flange_pose(q), T_fc, settle_s=0.0)
        baseline = float(np.linalg.norm(T_cam1_cam2[:3, 3]))
        w.write_pair(0, 0, 1, baseline, baseline, "test")
    return path
