"""Synthetic recordings written like the capture writes them, and how to compare a view read
back with what was written."""

from __future__ import annotations

import numpy as np

from armstereo.camera_model import Intrinsics
from armstereo.frame import Frame
from armstereo.recording import RecordingWriter
from armstereo.robot.arm_model import JOINT_NAMES as JOINTS
from armstereo.transforms import make_T, rot_x, rot_y, rot_z

__all__ = ["BASELINE", "JOINTS", "T0_NS", "assert_view_matches", "small_intrinsics",
           "synthetic_views", "write_synthetic"]

T0_NS = 1_700_000_000_123_456_789  # realistic epoch nanoseconds: needs all 64 bits of care
BASELINE = 0.05


def small_intrinsics(width: int = 48, height: int = 32, dist=None) -> Intrinsics:
    K = [[40.0, 0.0, (width - 1) / 2], [0.0, 41.0, (height - 1) / 2], [0.0, 0.0, 1.0]]
    return Intrinsics(width, height, K, np.zeros(5) if dist is None else dist)


def synthetic_views(n: int, intr: Intrinsics, seed: int = 0, depth: bool = True) -> list[dict]:
    """``n`` views moving by BASELINE along camera x; random images and depth with NaNs."""
    rng = np.random.default_rng(seed)
    T_flange_camera = make_T(rot_z(0.3) @ rot_x(0.05), [0.0, -0.07, 0.04])
    T_start = make_T(rot_x(np.pi) @ rot_y(0.2) @ rot_z(0.7), [0.41, -0.13, 0.52])
    views = []
    for k in range(n):
        step = T_start[:3, :3] @ T_flange_camera[:3, :3] @ np.array([BASELINE * k, 0, 0])
        T_base_flange = T_start.copy()
        T_base_flange[:3, 3] += step
        image = rng.integers(0, 256, (intr.height, intr.width, 3), dtype=np.uint8)
        d = None
        if depth:
            d = rng.uniform(0.3, 0.6, (intr.height, intr.width)).astype(np.float32)
            d[rng.random(d.shape) < 0.1] = np.nan
        views.append({"view": k, "frame": Frame(image, T0_NS + k * 1_250_000_001, d),
                      "q": rng.uniform(-3, 3, 6), "T_base_flange": T_base_flange,
                      "T_flange_camera": T_flange_camera})
    return views


def write_synthetic(path, n_views: int = 3, *, intr: Intrinsics | None = None,
                    calibration: bool = True, pairs: bool = True, depth: bool = True,
                    image_format: str = "png", seed: int = 0,
                    point_cloud: bool = False) -> list[dict]:
    """Write a recording like the capture does (plus a point cloud); returns the views."""
    intr = intr or small_intrinsics()
    views = synthetic_views(n_views, intr, seed, depth)
    with RecordingWriter(path, metadata={"robot": "ur5e", "mount_toml": "name = 'm'\n[x]\n"},
                         image_format=image_format) as w:
        if calibration:
            w.write_calibration(intr, T0_NS - 1000)
        for v in views:
            w.write_view(v["view"], v["frame"], v["q"], JOINTS, v["T_base_flange"],
                         v["T_flange_camera"], settle_s=0.5)
            k = v["view"]
            if pairs and k > 0:
                w.write_pair(k - 1, k - 1, k, BASELINE, BASELINE, "x")
        if point_cloud:
            rng = np.random.default_rng(seed)
            w.write_point_cloud(rng.normal(size=(50, 3)), rng.integers(0, 256, (50, 3), np.uint8),
                                views[-1]["frame"].timestamp_ns + 1)
    return views


def assert_view_matches(view, original: dict) -> None:
    """Bit-for-bit image and depth, poses to 1e-12."""
    assert view.timestamp_ns == original["frame"].timestamp_ns
    assert np.array_equal(view.image, original["frame"].image)
    d = original["frame"].depth
    if d is None:
        assert view.depth is None
    else:
        assert view.depth.dtype == np.float32
        assert np.array_equal(view.depth, d, equal_nan=True)
    assert np.abs(view.T_base_flange - original["T_base_flange"]).max() < 1e-12
    assert np.abs(view.T_flange_camera - original["T_flange_camera"]).max() < 1e-12
    T_base_camera = original["T_base_flange"] @ original["T_flange_camera"]
    assert np.abs(view.T_base_camera - T_base_camera).max() < 1e-12
    assert np.array_equal(view.joint_positions, original["q"])
