"""Synthetic tabletop clouds with exact answers, for tests and benchmarks of the scene analysis:
an orthographic scan from straight above.

A vertical ray through every grid point (spacing ``spacing`` m) hits the highest surface of
the scene's primitives (table rectangle, boxes, upright cylinders, spheres); that hit becomes a
point, with Gaussian height noise and a colour per primitive (optionally a striped texture).
What is hidden from above (sides, table under objects) is not in the cloud, as with a camera
looking down. Clouds are in the base frame, metres.
"""

from __future__ import annotations

import math

import numpy as np

from armstereo.evaluation.scene_truth import SceneTruth, TruthPrimitive
from armstereo.scene.cloud import SceneCloud
from armstereo.transforms import make_T, rot_z

TABLE_HALF = (0.25, 0.2)


def table(z: float = 0.0, half=TABLE_HALF, T: np.ndarray | None = None) -> TruthPrimitive:
    T = make_T(np.eye(3), (0.0, 0.0, z)) if T is None else T
    return TruthPrimitive("table", "rectangle", T, tuple(half))


def box(name, x, y, sx, sy, sz, yaw_deg=0.0, z0=0.0) -> TruthPrimitive:
    return TruthPrimitive(name, "box", make_T(rot_z(math.radians(yaw_deg)), (x, y, z0 + sz / 2)),
                          (sx, sy, sz))


def cylinder(name, x, y, r, h, z0=0.0) -> TruthPrimitive:
    return TruthPrimitive(name, "cylinder", make_T(np.eye(3), (x, y, z0)), (r, h))


def sphere(name, x, y, r, z0=0.0) -> TruthPrimitive:
    return TruthPrimitive(name, "sphere", make_T(np.eye(3), (x, y, z0 + r)), (r,))


def default_truth() -> SceneTruth:
    """A table with a rotated box, a cylinder, a sphere and a flat book."""
    return SceneTruth([table(), box("crate", -0.1, 0.05, 0.12, 0.08, 0.1, yaw_deg=25.0),
                       cylinder("can", 0.1, 0.08, 0.035, 0.15), sphere("ball", 0.08, -0.1, 0.04),
                       box("book", -0.1, -0.1, 0.15, 0.1, 0.03, yaw_deg=-10.0)], "table")


def _top_z(p: TruthPrimitive, xy: np.ndarray) -> np.ndarray:
    """z where a vertical ray through ``xy`` (N, 2) first hits ``p`` from above (-inf: miss)."""
    T = p.T_base_local
    local = (xy - T[:2, 3]) @ T[:2, :2]  # rotation about z only (and identity for rectangles)
    out = np.full(len(xy), -np.inf)
    if p.kind == "rectangle":
        hit = (np.abs(local[:, 0]) <= p.dims[0]) & (np.abs(local[:, 1]) <= p.dims[1])
        out[hit] = T[2, 3] + local[hit] @ np.zeros(2)
    elif p.kind == "box":
        hit = (np.abs(local[:, 0]) <= p.dims[0] / 2) & (np.abs(local[:, 1]) <= p.dims[1] / 2)
        out[hit] = T[2, 3] + p.dims[2] / 2
    elif p.kind == "cylinder":
        hit = np.hypot(local[:, 0], local[:, 1]) <= p.dims[0]
        out[hit] = T[2, 3] + p.dims[1]
    else:
        rho2 = (local ** 2).sum(axis=1)
        hit = rho2 < p.dims[0] ** 2
        out[hit] = T[2, 3] + np.sqrt(p.dims[0] ** 2 - rho2[hit])
    return out


def scan(truth: SceneTruth, *, spacing: float = 0.001, noise: float = 0.0003, seed: int = 0,
         textured: tuple[str, ...] = (), extent=TABLE_HALF) -> SceneCloud:
    """The orthographic scan of ``truth`` over ``|x| <= extent[0], |y| <= extent[1]``."""
    rng = np.random.default_rng(seed)
    xs = np.arange(-extent[0], extent[0] + 1e-9, spacing)
    ys = np.arange(-extent[1], extent[1] + 1e-9, spacing)
    gx, gy = np.meshgrid(xs, ys)
    xy = np.column_stack([gx.ravel(), gy.ravel()])
    zs = np.stack([_top_z(p, xy) for p in truth.primitives])
    which = np.argmax(zs, axis=0)
    z = zs[which, np.arange(len(xy))]
    seen = np.isfinite(z)
    xy, z, which = xy[seen], z[seen], which[seen]
    pts = np.column_stack([xy, z + rng.normal(0.0, noise, len(z))])
    colors = np.zeros((len(pts), 3), dtype=np.uint8)
    for k, p in enumerate(truth.primitives):
        m = which == k
        base = np.array([60 + 40 * (k % 4), 80 + 30 * (k % 3), 200 - 35 * (k % 5)], float)
        shade = np.zeros(m.sum())
        if p.name in textured:  # 4 mm stripes: a busy pattern
            shade = 60 * np.sign(np.sin(2 * np.pi * pts[m, 0] / 0.004))
        colors[m] = np.clip(base + shade[:, None], 0, 255).astype(np.uint8)
    return SceneCloud(pts, colors, "base", "synthetic")
