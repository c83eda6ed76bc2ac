"""Camera rays for the mock renderer: one through every pixel centre, through the lens model.

:func:`ray_grid` gives the normalised rays ``(xn, yn, 1)`` of an :class:`Intrinsics` (OpenCV
distortion included; cached), with their per-pixel Jacobian for sub-pixel rays and per-row and
per-column bounds. :func:`footprint` and :func:`in_footprint` cull the rays that cannot hit a
primitive; :func:`aliasing_pixels` finds the pixels where one ray per pixel would alias.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from armstereo.camera_model import Intrinsics
from drivers.mock.primitives import Primitive

_UNDISTORT_TOL_PX = 0.01  # rays whose re-distorted pixel misses by more are dropped


@dataclass
class RayGrid:
    """Camera-frame rays ``(xn, yn, 1)`` through pixel centres (t along them is z-depth)."""

    xn: np.ndarray  # (H, W) float32 normalised x = X/Z; NaN where the lens model has no ray
    yn: np.ndarray
    jac: tuple  # d(xn, yn)/d(u, v) per pixel: (dxn/du, dxn/dv, dyn/du, dyn/dv), float32
    col_lo: np.ndarray  # per column min/max of xn, per row min/max of yn (for culling)
    col_hi: np.ndarray
    row_lo: np.ndarray
    row_hi: np.ndarray

    def subpixel_rays(self, rows: np.ndarray, cols: np.ndarray, s: int):
        """Rays (xn, yn), each (M * s * s,), at s x s sub-pixel positions in pixels
        (rows, cols), by first-order expansion of the centre rays (exact for a pinhole; the
        lens map is smooth, so the error with distortion is far below 1e-3 px)."""
        off = (np.arange(s, dtype=np.float32) + 0.5) / s - 0.5
        du = np.tile(off, s)[None, :]
        dv = np.repeat(off, s)[None, :]
        xu, xv, yu, yv = (j[rows, cols][:, None] for j in self.jac)
        xn = self.xn[rows, cols][:, None] + xu * du + xv * dv
        yn = self.yn[rows, cols][:, None] + yu * du + yv * dv
        return xn.ravel(), yn.ravel()


_RAY_CACHE: dict[tuple, RayGrid] = {}
_RAY_CACHE_SIZE = 8


def ray_grid(intr: Intrinsics) -> RayGrid:
    """Rays through the pixel centres (OpenCV: integer pixel coordinates), cached."""
    key = (intr.width, intr.height, intr.K.tobytes(), intr.dist.tobytes())
    grid = _RAY_CACHE.get(key)
    if grid is not None:
        return grid
    u, v = np.arange(intr.width, dtype=float), np.arange(intr.height, dtype=float)
    if not intr.has_distortion:
        yn = np.broadcast_to(((v - intr.cy) / intr.fy)[:, None], (v.size, u.size))
        xn = (u[None, :] - intr.cx - intr.K[0, 1] * yn) / intr.fx
    else:
        xn, yn = _undistort_grid(intr, u, v)
    xv, xu = np.gradient(xn)
    yv, yu = np.gradient(yn)
    jac = tuple(j.astype(np.float32) for j in (xu, xv, yu, yv))
    # float32 rays: half the memory traffic; depth is float32 anyway (rel. error ~1e-7)
    xn, yn = xn.astype(np.float32), yn.astype(np.float32)
    # Culling bounds ignore rays the lens model lacks (NaN): they never hit anything.
    nan_x, nan_y = np.isnan(xn), np.isnan(yn)
    grid = RayGrid(xn, yn, jac,
                    np.where(nan_x, np.inf, xn).min(axis=0),
                    np.where(nan_x, -np.inf, xn).max(axis=0),
                    np.where(nan_y, np.inf, yn).min(axis=1),
                    np.where(nan_y, -np.inf, yn).max(axis=1))
    if len(_RAY_CACHE) >= _RAY_CACHE_SIZE:
        _RAY_CACHE.pop(next(iter(_RAY_CACHE)))
    _RAY_CACHE[key] = grid
    return grid


def _undistort_grid(intr: Intrinsics, u: np.ndarray, v: np.ndarray):
    """Normalised ray coordinates of distorted pixels; NaN where undistortion does not
    reproduce the pixel (outside the region where the distortion model is invertible)."""
    uu, vv = np.meshgrid(u, v)
    pts = np.stack([uu.ravel(), vv.ravel()], axis=1)
    crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-12)
    und = cv2.undistortPointsIter(pts.reshape(-1, 1, 2), intr.K, intr.dist, None, None,
                                  crit).reshape(-1, 2)
    obj = np.concatenate([und, np.ones((len(und), 1))], axis=1)
    back, _ = cv2.projectPoints(obj, np.zeros(3), np.zeros(3), intr.K, intr.dist)
    bad = np.linalg.norm(back.reshape(-1, 2) - pts, axis=1) > _UNDISTORT_TOL_PX
    und[bad] = np.nan
    return und[:, 0].reshape(uu.shape), und[:, 1].reshape(uu.shape)



# A pixel is re-rendered with several rays when its 3x3 neighbourhood spans a silhouette or a
# crease (normals turning by more than ~18 deg) or its surface is seen at a grazing angle
# (compressed texture): there one centre sample would alias.
_CREASE_COS = 0.95
_GRAZING_COS = 0.3


def aliasing_pixels(idx: np.ndarray, normals: np.ndarray, grid: RayGrid) -> np.ndarray:
    """Boolean (H, W) mask of the pixels that need supersampling."""
    H, W = idx.shape
    ip = np.pad(idx, 1, mode="edge")
    npd = np.pad(normals, ((1, 1), (1, 1), (0, 0)), mode="edge")
    flag = np.zeros((H, W), dtype=bool)
    for dr in (0, 1, 2):
        for dc in (0, 1, 2):
            if dr == 1 and dc == 1:
                continue
            flag |= ip[dr:dr + H, dc:dc + W] != idx
            dot = np.einsum("ijk,ijk->ij", npd[dr:dr + H, dc:dc + W], normals)
            flag |= (dot < _CREASE_COS) & (idx >= 0)
    view = np.stack(np.broadcast_arrays(grid.xn, grid.yn, np.float32(1.0)), axis=-1)
    with np.errstate(invalid="ignore"):
        cos = np.abs(np.einsum("ijk,ijk->ij", view, normals)) / np.linalg.norm(view, axis=-1)
    flag |= (cos < _GRAZING_COS) & (idx >= 0)
    return flag


def footprint(prim: Primitive, T_camera_base: np.ndarray, grid: RayGrid):
    """(rows, cols) slices of the ray grid whose rays can hit ``prim`` (None if none).

    Conservative: the primitive lies inside the convex hull of its corners, whose pinhole
    projection bounds the normalised coordinates of every ray that can hit it.
    """
    c = prim.corners_base() @ T_camera_base[:3, :3].T + T_camera_base[:3, 3]
    if np.any(c[:, 2] <= 1e-6):
        return None if np.all(c[:, 2] <= 0) else (slice(None), slice(None))
    x, y = c[:, 0] / c[:, 2], c[:, 1] / c[:, 2]
    cols = np.flatnonzero((grid.col_hi >= x.min()) & (grid.col_lo <= x.max()))
    rows = np.flatnonzero((grid.row_hi >= y.min()) & (grid.row_lo <= y.max()))
    if cols.size == 0 or rows.size == 0:
        return None
    return slice(rows[0], rows[-1] + 1), slice(cols[0], cols[-1] + 1)


def in_footprint(prim: Primitive, T_camera_base: np.ndarray, xn, yn) -> np.ndarray:
    """Boolean mask of the camera rays (xn, yn, 1) that can hit ``prim`` (conservative)."""
    c = prim.corners_base() @ T_camera_base[:3, :3].T + T_camera_base[:3, 3]
    if np.any(c[:, 2] <= 1e-6):
        return np.full(xn.shape, bool(np.any(c[:, 2] > 0)))
    x, y = c[:, 0] / c[:, 2], c[:, 1] / c[:, 2]
    with np.errstate(invalid="ignore"):
        return (xn >= x.min()) & (xn <= x.max()) & (yn >= y.min()) & (yn <= y.max())

