"""The ready-made mock scenes, in the controller's ``base`` frame (metres): the demo's table
(:func:`default_table_scene`) and the baseline sweep's planar targets
(:func:`planar_target_scene`). The desk of the realistic profile is ``drivers/mock/desk.py``.

The table top is the plane z = 0 (the arm stands on it), objects sit around
:data:`SCENE_CENTER`. The building blocks live in their own modules and are re-exported here:
textures (:mod:`drivers.mock.texture`), primitives (:mod:`drivers.mock.primitives`) and the
renderer (:class:`drivers.mock.render.Scene`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import NamedTuple

import cv2
import numpy as np

from armstereo.camera_model import Intrinsics
from armstereo.errors import ConfigError
from armstereo.transforms import as_rigid, invert, make_T
from drivers.mock.primitives import Box, Cylinder, Primitive, Rectangle, Sphere
from drivers.mock.render import Scene
from drivers.mock.texture import PhotoTexture, SurfaceTexture, Texture

__all__ = [
    "FLOOR_Z", "SCENE_CENTER", "TABLE_HALF_SIZE", "Box", "Cylinder", "PhotoTexture",
    "PlanarTarget", "Primitive", "Rectangle", "Scene", "Sphere", "SurfaceTexture",
    "TargetScene", "Texture", "default_table_scene", "planar_target_scene",
]

# Centre of the default table scene, base-frame (x, y) in metres. At their ready configuration
# UR arms hold the flange in front of the base, looking straight down (UR5e: flange at
# (-0.492, -0.133, 0.488) m, checked against an independent DH computation). This point is
# 0.47 m from the base axis: UR5e, UR5, UR10e and UR16e put the camera 0.55 m above it with
# joints 0.1 rad inside their limits and sigma_min ~ 0.2, and keep that for camera baselines of
# +-0.3 m along the camera's x axis (base y). The UR3e (0.5 m reach) cannot: use a lower height.
SCENE_CENTER = (-0.45, -0.13)


# --------------------------------------------------------------------------------------------
# Ready-made scenes


def _texture(dark, light, seed: int, scale: float = 1.0) -> Texture:
    return Texture(dark, light, min_wavelength=0.008 * scale, max_wavelength=0.022 * scale,
                   seed=seed)


# (name, kind, offset from SCENE_CENTER (dx, dy) m, dimensions, yaw, dark BGR, light BGR)
_TABLE_OBJECTS = (
    ("crate", "box", (0.06, -0.10), (0.12, 0.08, 0.10), 0.3, (30, 30, 120), (150, 170, 250)),
    ("book", "box", (-0.10, 0.09), (0.16, 0.11, 0.025), -0.2, (110, 40, 20), (250, 200, 150)),
    ("can", "cylinder", (-0.08, -0.12), (0.035, 0.15), 0.0, (30, 90, 30), (170, 240, 170)),
    ("puck", "cylinder", (0.10, 0.12), (0.05, 0.04), 0.0, (20, 90, 110), (140, 230, 250)),
    ("ball", "sphere", (0.02, 0.01), (0.045,), 0.0, (100, 30, 100), (240, 170, 240)),
    ("block", "box", (0.13, 0.02), (0.05, 0.05, 0.06), 0.7, (100, 100, 20), (250, 240, 150)),
    ("marble", "sphere", (-0.14, -0.03), (0.025,), 0.0, (40, 40, 40), (230, 230, 230)),
)
TABLE_HALF_SIZE = (0.6, 0.5)  # table top half extents along base x and y (m)
FLOOR_Z = -0.75  # floor below the table top (m)


def default_table_scene(seed: int = 0, *, floor: bool = True) -> Scene:
    """The demo scene: a textured table top (z = 0, 1.2 m x 1.0 m centred at SCENE_CENTER)
    with seven objects 2.5 to 15 cm tall (boxes, some rotated; cylinders; spheres), each with
    its own colours and texture, all within 0.2 m of SCENE_CENTER. ``seed`` changes the
    textures only; ``floor`` adds a floor plane 0.75 m below the table top."""
    cx, cy = SCENE_CENTER
    prims: list[Primitive] = [Rectangle(make_T(np.eye(3), (cx, cy, 0.0)), *TABLE_HALF_SIZE,
                                        _texture((35, 60, 95), (150, 195, 235), seed * 1000),
                                        name="table")]
    for k, (name, kind, (dx, dy), dims, yaw, dark, light) in enumerate(_TABLE_OBJECTS, 1):
        tex = _texture(dark, light, seed * 1000 + k)
        x, y = cx + dx, cy + dy
        if kind == "box":
            prims.append(Box((x, y, dims[2] / 2), dims, tex, yaw=yaw, name=name))
        elif kind == "cylinder":
            prims.append(Cylinder((x, y), dims[0], dims[1], tex, name=name))
        else:
            prims.append(Sphere((x, y, dims[0]), dims[0], tex, name=name))
    if floor:
        prims.append(Rectangle(make_T(np.eye(3), (cx, cy, FLOOR_Z)), 3.0, 3.0,
                               _texture((50, 50, 50), (125, 125, 125), seed * 1000 + 99, 3.0),
                               name="floor"))
    return Scene(prims, support="table")


@dataclass(frozen=True)
class PlanarTarget:
    """A square textured target facing the reference camera (for the baseline sweep).

    ``index`` is its position in the list of distances given;
    ``distance`` is its true z-depth along the reference camera's optical axis (m);
    ``T_base_target`` has z pointing at the camera and x along the camera's x axis;
    ``pixel_box`` = (u_min, v_min, u_max, v_max) of its corners in the reference image.
    """

    index: int
    distance: float
    T_base_target: np.ndarray
    half_size: float
    pixel_box: tuple[float, float, float, float]

    def corners_base(self) -> np.ndarray:
        """The four corners (4, 3), base frame."""
        return _square_corners(self.T_base_target, self.half_size)

    def pixel_box_in(self, T_base_camera: np.ndarray, intrinsics: Intrinsics):
        """(u_min, v_min, u_max, v_max) of the corners seen by another camera (with its lens
        distortion); useful for scoring the right view or a moved camera."""
        return _pixel_box(self.corners_base(), T_base_camera, intrinsics)


class TargetScene(NamedTuple):
    """A sweep scene and its targets (in the order of the distances given)."""

    scene: Scene
    targets: tuple[PlanarTarget, ...]


def planar_target_scene(distances: Sequence[float], T_base_camera: np.ndarray,
                        intrinsics: Intrinsics, *, max_baseline: float = 0.0,
                        fill: float = 0.7, margin_px: float = 16.0, backdrop: bool = True,
                        seed: int = 0) -> TargetScene:
    """Fronto-parallel square targets at the given z-depths from a reference camera.

    Targets sit side by side in a grid over the image, nearest on the left of each row, each
    filling ``fill`` of its grid cell, so every target stays well inside the view. A second
    camera shifted by up to ``max_baseline`` metres along the reference camera's x axis
    (positive: to the right) still sees every target whole, and no target hides another from
    it. Textures scale with distance (about 9 px per finest wavelength at any distance).
    ``backdrop`` adds a textured wall behind the farthest target. The scene holds nothing else.
    """
    T = as_rigid(T_base_camera, "camera pose T_base_camera")
    d = np.asarray(distances, dtype=float).reshape(-1)
    if d.size == 0 or not np.all(np.isfinite(d)) or np.any(d <= 0.05):
        raise ConfigError("target distances must be finite and > 0.05 m, got "
                          + ", ".join(f"{v:g}" for v in d))
    if not 0.1 <= fill <= 0.95:
        raise ConfigError(f"fill must be in [0.1, 0.95], got {fill}")
    order = np.argsort(d, kind="stable")
    cells = _target_cells(d[order], intrinsics, max_baseline, margin_px)
    R_base_target = T[:3, :3] @ np.diag([1.0, -1.0, -1.0])
    targets: list[PlanarTarget] = []
    prims: list[Primitive] = []
    for k, (z, (uc, vc, cell)) in enumerate(zip(d[order], cells, strict=True)):
        half = fill * cell / 2 * z / intrinsics.fx
        xn, yn = _normalised(intrinsics, uc, vc)
        T_bt = make_T(R_base_target, T[:3, :3] @ np.array([xn * z, yn * z, z]) + T[:3, 3])
        i = int(order[k])
        rng = np.random.default_rng(seed * 1000 + i)
        dark, light = rng.uniform(10, 90, 3), rng.uniform(170, 250, 3)
        prims.append(Rectangle(T_bt, half, half, _texture(dark, light, seed * 1000 + i,
                                                          z / 0.55), name=f"target{i}"))
        box = _pixel_box(_square_corners(T_bt, half), T, intrinsics)
        targets.append(PlanarTarget(i, float(z), T_bt, half, box))
    targets.sort(key=lambda tg: tg.index)
    if backdrop:
        zb = 1.25 * float(d.max()) + 0.3
        hx = zb * (intrinsics.width + 2 * abs(max_baseline) * intrinsics.fx / zb) / intrinsics.fx
        hy = zb * intrinsics.height / intrinsics.fy
        T_bb = make_T(R_base_target, T[:3, :3] @ np.array([0.0, 0.0, zb]) + T[:3, 3])
        prims.append(Rectangle(T_bb, hx, hy, _texture((60, 60, 60), (190, 190, 190),
                                                      seed * 1000 + 999, zb / 0.55),
                               name="backdrop"))
    light = -T[:3, 2] + 0.3 * T[:3, 0] - 0.3 * T[:3, 1]  # from behind the camera, up-left
    return TargetScene(Scene(prims, light_dir=light), tuple(targets))


def _target_cells(d_sorted: np.ndarray, intr: Intrinsics, max_baseline: float,
                  margin_px: float):
    """Grid cells (u_centre, v_centre, side_px) for targets sorted nearest first."""
    shift = intr.fx * abs(max_baseline) / float(d_sorted[0])  # largest disparity, px
    u_lo, u_hi = margin_px, intr.width - 1 - margin_px
    if max_baseline > 0:
        u_lo += shift
    else:
        u_hi -= shift
    v_lo, v_hi = margin_px, intr.height - 1 - margin_px
    n = len(d_sorted)
    best = max(range(1, n + 1), key=lambda r: min((u_hi - u_lo) / math.ceil(n / r),
                                                 (v_hi - v_lo) / r))
    rows, cols = best, math.ceil(n / best)
    cw, ch = (u_hi - u_lo) / cols, (v_hi - v_lo) / rows
    side = min(cw, ch)
    if side < 40:
        raise ConfigError(f"{n} targets with a {max_baseline} m baseline leave {side:.0f} px "
                          f"per target (need >= 40); use fewer targets or a smaller baseline")
    cells = []
    for k in range(n):
        r, c = divmod(k, cols)
        if max_baseline < 0:
            c = cols - 1 - c  # the second camera is to the left: nearest on the right
        cells.append((u_lo + (c + 0.5) * cw, v_lo + (r + 0.5) * ch, side))
    return cells


def _square_corners(T_base_target: np.ndarray, h: float) -> np.ndarray:
    c = np.array([[-h, -h, 0], [h, -h, 0], [h, h, 0], [-h, h, 0]], dtype=float)
    return c @ T_base_target[:3, :3].T + T_base_target[:3, 3]


def _normalised(intr: Intrinsics, u: float, v: float) -> tuple[float, float]:
    pt = np.array([[[u, v]]], dtype=np.float64)
    crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-12)
    x, y = cv2.undistortPointsIter(pt, intr.K, intr.dist, None, None, crit).reshape(2)
    return float(x), float(y)


def _pixel_box(points_base: np.ndarray, T_base_camera: np.ndarray, intr: Intrinsics):
    T_cb = invert(T_base_camera)
    uv, _ = cv2.projectPoints(points_base @ T_cb[:3, :3].T + T_cb[:3, 3], np.zeros(3),
                              np.zeros(3), intr.K, intr.dist)
    uv = uv.reshape(-1, 2)
    return (float(uv[:, 0].min()), float(uv[:, 1].min()), float(uv[:, 0].max()),
            float(uv[:, 1].max()))
