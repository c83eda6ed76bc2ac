"""Synthetic two-view data for the camera-motion study: scenes, motions, projections.

Camera 1 sits at the origin looking along +z (OpenCV frame, metres); the scene is centred
:data:`SCENE_DEPTH_M` in front of it. Camera 2's pose follows the motion kind. All randomness
comes from the generator passed in, so a seed fixes every trial.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from armstereo.transforms import make_T, rotvec_to_matrix

SCENES = ("cube", "cloud")
MOTIONS = ("rotation_only", "lateral", "forward", "general")
IMAGE_SIZE = (640, 480)
FOCAL_PX = 800.0
SCENE_DEPTH_M = 5.0
SCENE_SIZE_M = 2.5  # cube side / cloud box side
BASELINE_M = 0.5  # 10 % of the scene distance
ROTATION_DEG = (3.0, 10.0)  # range of the relative rotation for rotation-only and general
MAX_DRAWS = 50


@dataclass(frozen=True)
class TwoViews:
    """Noise-free projections ``x1``, ``x2`` ((N, 2) px) of the same points, both inside both
    images; ``K`` (3x3) for both cameras; ``T_cam1_cam2`` camera 2's pose in camera 1 (4x4)."""

    x1: np.ndarray
    x2: np.ndarray
    K: np.ndarray
    T_cam1_cam2: np.ndarray


def camera_matrix() -> np.ndarray:
    w, h = IMAGE_SIZE
    return np.array([[FOCAL_PX, 0.0, (w - 1) / 2.0], [0.0, FOCAL_PX, (h - 1) / 2.0],
                     [0.0, 0.0, 1.0]])


def scene_points(scene: str, n: int, rng: np.random.Generator) -> np.ndarray:
    """``n`` points (camera-1 frame, m): on a randomly turned cube's faces, or in a box."""
    half = SCENE_SIZE_M / 2.0
    if scene == "cube":
        p = rng.uniform(-half, half, (n, 3))
        face = rng.integers(0, 3, n)
        p[np.arange(n), face] = rng.choice([-half, half], n)
        R = rotvec_to_matrix(rng.normal(0.0, 1.0, 3))
        p = p @ R.T
    elif scene == "cloud":
        p = rng.uniform(-half, half, (n, 3))
    else:
        raise ValueError(f"unknown scene {scene!r}; choose one of {SCENES}")
    return p + np.array([0.0, 0.0, SCENE_DEPTH_M])


def motion_pose(motion: str, rng: np.random.Generator) -> np.ndarray:
    """``T_cam1_cam2`` (4x4, m) for a motion kind (see :data:`MOTIONS`)."""
    angle = np.radians(rng.uniform(*ROTATION_DEG))
    axis = rng.normal(0.0, 1.0, 3)
    axis /= np.linalg.norm(axis)
    if motion == "rotation_only":
        return make_T(rotvec_to_matrix(angle * axis), np.zeros(3))
    if motion == "lateral":
        return make_T(np.eye(3), [BASELINE_M, 0.0, 0.0])
    if motion == "forward":
        return make_T(np.eye(3), [0.0, 0.0, BASELINE_M])
    if motion == "general":
        t = rng.normal(0.0, 1.0, 3)
        return make_T(rotvec_to_matrix(angle * axis), BASELINE_M * t / np.linalg.norm(t))
    raise ValueError(f"unknown motion {motion!r}; choose one of {MOTIONS}")


def project(K: np.ndarray, T_cam1_cam: np.ndarray, p: np.ndarray) -> tuple[np.ndarray,
                                                                          np.ndarray]:
    """Pixels of camera-1-frame points in a camera at ``T_cam1_cam``, and an in-front mask."""
    pc = (p - T_cam1_cam[:3, 3]) @ T_cam1_cam[:3, :3]
    h = pc @ K.T
    with np.errstate(divide="ignore", invalid="ignore"):
        return h[:, :2] / h[:, 2:], pc[:, 2] > 0


def two_views(scene: str, motion: str, n: int, rng: np.random.Generator) -> TwoViews:
    """``n`` points of ``scene`` seen by camera 1 and by camera 2 after ``motion``."""
    K = camera_matrix()
    T = motion_pose(motion, rng)
    keep1, keep2 = [], []
    for _ in range(MAX_DRAWS):
        if sum(len(k) for k in keep1) >= n:
            break
        p = scene_points(scene, 4 * n, rng)
        x1, f1 = project(K, np.eye(4), p)
        x2, f2 = project(K, T, p)
        ok = f1 & f2 & _inside(x1) & _inside(x2)
        keep1.append(x1[ok])
        keep2.append(x2[ok])
    else:
        raise RuntimeError(f"{motion} motion leaves too few {scene} points in both views")
    return TwoViews(np.vstack(keep1)[:n], np.vstack(keep2)[:n], K, T)


def _inside(x: np.ndarray) -> np.ndarray:
    w, h = IMAGE_SIZE
    return (x[:, 0] >= 0) & (x[:, 0] <= w - 1) & (x[:, 1] >= 0) & (x[:, 1] <= h - 1)
