"""Surface extraction from a TSDF, view support, colours, and even surface sampling.

Marching cubes (scikit-image, Lewiner) runs only on cubes whose **eight corners are all
observed**. A cube with an unobserved corner mixes a real distance with the "unknown" value:
behind every surface, where observed voxels (-trunc .. 0) meet the unseen space, it would
produce a ghost sheet one truncation distance behind the real one. scikit-image's ``mask``
enables the cube whose *far* corner (index + 1 on every axis) is True, so the eight-corner
test is written into the mask shifted by one (checked in ``tests/armstereo/fusion``).

View support: a surface point is *seen* by a depth frame when it projects inside the image,
in front of the camera, onto a valid depth within ``tolerance`` of its own depth. The number of
frames (stereo pairs) that see a point confirms it; their images give its colour.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from armstereo.errors import ConfigError
from armstereo.fusion.tsdf import DepthFrame, TsdfVolume

DEFAULT_MIN_WEIGHT = 1.0  # one observation: a surface seen by a single pair stays in the mesh
UNSEEN_BGR = (128, 128, 128)


@dataclass(frozen=True)
class Mesh:
    """A triangle mesh in the base frame: ``vertices`` (N, 3) float32 m, ``faces`` (M, 3)
    int32 vertex indices (counter-clockwise seen from outside, i.e. from the cameras' side),
    ``colors`` (N, 3) uint8 BGR."""

    vertices: np.ndarray
    faces: np.ndarray
    colors: np.ndarray

    def __post_init__(self) -> None:
        v, f, c = np.asarray(self.vertices), np.asarray(self.faces), np.asarray(self.colors)
        if v.ndim != 2 or v.shape[1] != 3 or f.ndim != 2 or f.shape[1] != 3:
            raise ConfigError(f"mesh needs (N, 3) vertices and (M, 3) faces, got {v.shape}, "
                              f"{f.shape}")
        if c.shape != v.shape or c.dtype != np.uint8:
            raise ConfigError(f"mesh colours must be uint8 {v.shape}, got {c.dtype} {c.shape}")
        if f.size and (f.min() < 0 or f.max() >= len(v)):
            raise ConfigError("mesh faces index vertices that do not exist")
        object.__setattr__(self, "vertices", np.ascontiguousarray(v, dtype=np.float32))
        object.__setattr__(self, "faces", np.ascontiguousarray(f, dtype=np.int32))

    @classmethod
    def empty(cls) -> Mesh:
        return cls(np.zeros((0, 3), np.float32), np.zeros((0, 3), np.int32),
                   np.zeros((0, 3), np.uint8))

    def __len__(self) -> int:
        return len(self.faces)

    def triangle_areas(self) -> np.ndarray:
        """Area (M,) of every face (m^2)."""
        a, b, c = (self.vertices[self.faces[:, i]].astype(np.float64) for i in range(3))
        return 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1)

    def area(self) -> float:
        return float(self.triangle_areas().sum())


def cube_mask(observed: np.ndarray) -> np.ndarray:
    """scikit-image ``mask`` that enables exactly the cubes with all eight corners observed."""
    o = observed
    all8 = (o[:-1, :-1, :-1] & o[1:, :-1, :-1] & o[:-1, 1:, :-1] & o[1:, 1:, :-1]
            & o[:-1, :-1, 1:] & o[1:, :-1, 1:] & o[:-1, 1:, 1:] & o[1:, 1:, 1:])
    mask = np.zeros(o.shape, dtype=bool)
    mask[1:, 1:, 1:] = all8  # scikit-image reads cube (i-1 .. i) from mask[i]
    return mask


def extract_mesh(volume: TsdfVolume, min_weight: float = DEFAULT_MIN_WEIGHT) -> Mesh:
    """The zero level of ``volume`` where every cube corner has ``min_weight`` of observations
    (uncoloured: grey). Empty when no observed cube holds a zero crossing."""
    from skimage.measure import marching_cubes  # heavy import, only where meshes are made

    if not min_weight > 0:
        raise ConfigError(f"min_weight must be > 0, got {min_weight}")
    observed = volume.observed(min_weight)
    mask = cube_mask(observed)
    crop = _bounds(mask)
    if crop is None:
        return Mesh.empty()
    lo = np.array([s.start for s in crop]) - 1  # the cubes need their near corners too
    box = tuple(slice(a, s.stop) for a, s in zip(lo, crop, strict=True))
    values, sub_mask = volume.tsdf[box], mask[box]
    seen = values[observed[box]]
    if not (seen.min() <= 0 <= seen.max()) or seen.min() == seen.max():
        return Mesh.empty()
    try:
        verts, faces, _, _ = marching_cubes(values, 0.0, mask=sub_mask, allow_degenerate=False)
    except (RuntimeError, ValueError):  # "no surface found" on masked volumes
        return Mesh.empty()
    points = volume.voxel_points(verts + lo)
    return Mesh(points.astype(np.float32), faces.astype(np.int32),
                np.full((len(points), 3), UNSEEN_BGR, np.uint8))


def _bounds(mask: np.ndarray) -> tuple[slice, slice, slice] | None:
    """Smallest box of slices holding every True of ``mask`` (None if there is none)."""
    if not mask.any():
        return None
    out = []
    for axis in range(3):
        other = tuple(a for a in range(3) if a != axis)
        idx = np.flatnonzero(mask.any(axis=other))
        out.append(slice(int(idx[0]), int(idx[-1]) + 1))
    return tuple(out)


@dataclass(frozen=True)
class Support:
    """Per point: ``views`` (N,) how many frames see it, ``colors`` (N, 3) uint8 BGR mean of
    their pixels (UNSEEN_BGR where none does), ``per_frame`` (F,) points each frame sees."""

    views: np.ndarray
    colors: np.ndarray
    per_frame: np.ndarray


def view_support(points: np.ndarray, frames: Sequence[DepthFrame], tolerance: float) -> Support:
    """Which frames see each base-frame point (N, 3) within ``tolerance`` m of their depth."""
    if not tolerance > 0:
        raise ConfigError(f"support tolerance must be > 0 m, got {tolerance}")
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    views = np.zeros(len(pts), dtype=np.int32)
    color_sum = np.zeros((len(pts), 3), dtype=np.float64)
    color_n = np.zeros(len(pts), dtype=np.int32)
    per_frame = np.zeros(len(frames), dtype=np.int64)
    for f, frame in enumerate(frames):
        u, v, z = frame.project(pts)
        h, w = frame.depth.shape
        iu, iv = np.rint(u), np.rint(v)
        inside = (z > 0) & (iu >= 0) & (iu < w) & (iv >= 0) & (iv < h)
        idx = np.flatnonzero(inside)
        r, c = iv[idx].astype(np.intp), iu[idx].astype(np.intp)
        d = frame.depth[r, c]
        with np.errstate(invalid="ignore"):
            seen = np.abs(d - z[idx]) <= tolerance  # False for NaN depth
        idx, r, c = idx[seen], r[seen], c[seen]
        views[idx] += 1
        per_frame[f] = len(idx)
        if frame.image is not None:
            color_sum[idx] += frame.image[r, c].reshape(-1, 3)
            color_n[idx] += 1
    colors = np.empty((len(pts), 3), dtype=np.uint8)
    colors[:] = UNSEEN_BGR
    have = color_n > 0
    colors[have] = np.clip(np.rint(color_sum[have] / color_n[have, None]), 0, 255)
    return Support(views, colors, per_frame)



def fused_cloud(mesh: Mesh, frames: Sequence[DepthFrame], tolerance: float,
                min_views: int = 2) -> tuple[Mesh, np.ndarray, np.ndarray, Support]:
    """Colour the mesh from the frames that see each vertex, and keep as the fused cloud the
    vertices at least ``min_views`` frames (pairs) see: ``(coloured mesh, points (K, 3),
    colours (K, 3) BGR, support)``. A surface only one pair saw stays in the mesh (it is all
    we know there) but is not confirmed, so it is left out of the cloud."""
    if min_views < 1:
        raise ConfigError(f"min_views must be >= 1, got {min_views}")
    support = view_support(mesh.vertices, frames, tolerance)
    keep = support.views >= min_views
    coloured = Mesh(mesh.vertices, mesh.faces, support.colors)
    return coloured, mesh.vertices[keep], support.colors[keep], support
