"""Synthetic correspondences with a known fundamental matrix (test helper, no images)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from armstereo.transforms import make_T, rot_x, rot_y

K = np.array([[800.0, 0.0, 319.5], [0.0, 800.0, 239.5], [0.0, 0.0, 1.0]])
SIZE = (640, 480)
# camera 2 in camera 1: 0.5 m to the right, a little up and forward, turned by a few degrees
T_CAM1_CAM2 = make_T(rot_y(np.radians(6.0)) @ rot_x(np.radians(2.0)), [0.5, -0.05, 0.1])


@dataclass
class Correspondences:
    x1: np.ndarray
    x2: np.ndarray
    true1: np.ndarray
    true2: np.ndarray
    inlier: np.ndarray
    T_cam1_cam2: np.ndarray


def project(T_cam1_cam: np.ndarray, points: np.ndarray) -> np.ndarray:
    pc = (points - T_cam1_cam[:3, 3]) @ T_cam1_cam[:3, :3]
    h = pc @ K.T
    return h[:, :2] / h[:, 2:]


def correspondences(n: int = 200, *, noise: float = 0.5, outliers: float = 0.0, seed: int = 0,
                    T_cam1_cam2: np.ndarray = T_CAM1_CAM2,
                    planar: bool = False) -> Correspondences:
    """Points in a 2.5 m box 4-6.5 m ahead (or on one slanted plane), seen by both cameras,
    Gaussian noise of ``noise`` px, a share ``outliers`` of x2 replaced by uniform points."""
    rng = np.random.default_rng(seed)
    p = np.c_[rng.uniform(-1.25, 1.25, n), rng.uniform(-1.0, 1.0, n), rng.uniform(4.0, 6.5, n)]
    if planar:
        p[:, 2] = 5.0 + 0.3 * p[:, 0] - 0.2 * p[:, 1]
    t1, t2 = project(np.eye(4), p), project(T_cam1_cam2, p)
    x1 = t1 + rng.normal(0.0, noise, t1.shape)
    x2 = t2 + rng.normal(0.0, noise, t2.shape)
    bad = np.zeros(n, bool)
    bad[rng.choice(n, int(round(outliers * n)), replace=False)] = True
    x2[bad] = rng.uniform((0, 0), SIZE, (int(bad.sum()), 2))
    return Correspondences(x1, x2, t1, t2, ~bad, T_cam1_cam2)
