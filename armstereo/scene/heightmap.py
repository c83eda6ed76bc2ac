"""2.5-D height map over the support plane, and a coarser occupancy grid for a motion planner.

**Height map**: a grid in the plane frame (columns along the plane's u axis, rows along v,
row-major), cell ``cell_m`` (5 mm by default). Each cell holds the highest point above the
plane that falls into it (m, float32); cells no point falls into are *unknown* (NaN): outside
the view, or hidden behind objects (the shadows beside tall objects). The grid's corner is
snapped to a multiple of the cell size, so maps of the same scene line up.

**Occupancy** (for a planner; written as ``occupancy.npz``): voxels of ``cell_m`` (20 mm by
default) in the same plane frame, stacked from the plane up. ``occupancy[k, j, i]`` (Z-Y-X, as
Foxglove's VoxelGrid) is :data:`OCCUPIED` (100) from the plane up to the highest surface seen in
the column, :data:`FREE` (0) above it, and :data:`UNKNOWN` (-1) in every voxel of a column no
fine cell of which was seen. Below a surface seen from above, nothing is known, so those voxels
count as occupied: the map is conservative for a planner. Heights below ``min_height`` count
as the plane (free). The support itself lies below the grid's bottom face; a planner adds it
as a box. ``T_base_grid`` places the grid's corner (cell (0, 0, 0)'s corner nearest the
origin) in the base frame; cell (k, j, i) spans ``[i, i+1) x [j, j+1) x [k, k+1)`` cells along
the grid's x, y, z axes.
"""

from __future__ import annotations

import io
import math
from dataclasses import dataclass

import numpy as np

from armstereo.errors import ConfigError

UNKNOWN = -1
FREE = 0
OCCUPIED = 100
MAX_CELLS = 50_000_000  # refuse grids larger than this (a cloud far bigger than a table)


@dataclass(frozen=True)
class HeightMap:
    """``heights`` (rows, cols) float32 m above the plane, NaN = unknown; ``origin_uv`` the
    plane coordinates of the grid corner; ``cell_m``; ``T_base_plane`` (module doc)."""

    heights: np.ndarray
    origin_uv: tuple[float, float]
    cell_m: float
    T_base_plane: np.ndarray

    @property
    def T_base_grid(self) -> np.ndarray:
        T = np.eye(4)
        T[:2, 3] = self.origin_uv
        return self.T_base_plane @ T

    @property
    def known_share(self) -> float:
        return float(np.isfinite(self.heights).mean())

    def cell_of(self, uv: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(row, col) integer indices of plane points ``uv`` (N, 2) (may lie outside)."""
        ij = np.floor((np.asarray(uv) - self.origin_uv) / self.cell_m).astype(np.int64)
        return ij[:, 1], ij[:, 0]


@dataclass(frozen=True)
class Occupancy:
    """``grid`` (nz, ny, nx) int8 of UNKNOWN/FREE/OCCUPIED, ``cell_m``, ``T_base_grid``."""

    grid: np.ndarray
    cell_m: float
    T_base_grid: np.ndarray

    def npz_bytes(self) -> bytes:
        """The ``occupancy.npz`` file: keys ``occupancy`` (nz, ny, nx) int8, ``cell_m``,
        ``T_base_grid`` (4, 4) and ``values`` (the legend, as text)."""
        buf = io.BytesIO()
        np.savez_compressed(buf, occupancy=self.grid, cell_m=np.float64(self.cell_m),
                            T_base_grid=self.T_base_grid,
                            values=np.array([f"{UNKNOWN}=unknown", f"{FREE}=free",
                                             f"{OCCUPIED}=occupied"]))
        return buf.getvalue()


def height_map(uvh: np.ndarray, T_base_plane: np.ndarray, cell_m: float) -> HeightMap:
    """Height map of points ``uvh`` (N, 3, plane coordinates, m); the caller passes the
    points on and above the plane only."""
    if not (math.isfinite(cell_m) and cell_m > 0):
        raise ConfigError(f"height map cell must be a positive length in metres, got {cell_m}")
    lo = np.floor(uvh[:, :2].min(axis=0) / cell_m) * cell_m
    ij = np.floor((uvh[:, :2] - lo) / cell_m).astype(np.int64)
    rows, cols = int(ij[:, 1].max()) + 1, int(ij[:, 0].max()) + 1
    if rows * cols > MAX_CELLS:
        raise ConfigError(f"a {cell_m * 1000:g} mm height map of this cloud would have "
                          f"{rows} x {cols} cells (limit {MAX_CELLS}); use a larger --cell")
    flat = ij[:, 1] * cols + ij[:, 0]
    order = np.argsort(flat, kind="stable")
    flat_s, h_s = flat[order], uvh[order, 2]
    starts = np.flatnonzero(np.r_[True, flat_s[1:] != flat_s[:-1]])
    heights = np.full(rows * cols, np.nan, dtype=np.float32)
    heights[flat_s[starts]] = np.maximum.reduceat(h_s, starts)
    return HeightMap(heights.reshape(rows, cols), (float(lo[0]), float(lo[1])), float(cell_m),
                     np.asarray(T_base_plane, dtype=float))


def occupancy(hmap: HeightMap, cell_m: float, *, min_height: float = 0.0,
              top_m: float | None = None) -> Occupancy:
    """Coarse voxel occupancy of ``hmap`` (module doc). ``cell_m`` is rounded to a whole
    number of height-map cells; ``top_m`` is the grid's height (default: the highest surface
    plus one voxel)."""
    k = max(1, int(round(cell_m / hmap.cell_m)))
    cell = k * hmap.cell_m
    h = hmap.heights
    rows, cols = -(-h.shape[0] // k), -(-h.shape[1] // k)
    padded = np.full((rows * k, cols * k), np.nan, dtype=np.float32)
    padded[:h.shape[0], :h.shape[1]] = h
    blocks = padded.reshape(rows, k, cols, k).transpose(0, 2, 1, 3).reshape(rows, cols, k * k)
    known = np.isfinite(blocks).any(axis=2)
    top = np.where(known, np.nanmax(np.where(np.isfinite(blocks), blocks, -np.inf), axis=2),
                   0.0)
    top = np.where(top < min_height, 0.0, top)
    highest = float(top.max()) if known.any() else 0.0
    nz = max(1, int(math.ceil((top_m if top_m is not None else highest + cell) / cell)))
    z_lo = np.arange(nz)[:, None, None] * cell
    grid = np.where(z_lo < top[None], OCCUPIED, FREE).astype(np.int8)
    grid[:, ~known] = UNKNOWN
    T = hmap.T_base_grid
    return Occupancy(grid, cell, T)
