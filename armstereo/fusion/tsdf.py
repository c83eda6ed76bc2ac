"""A truncated signed distance volume (TSDF) over a box in the base frame, fed by depth maps.

Grid: voxel ``(i, j, k)`` is the point ``roi.lo + (i, j, k) * voxel`` (base frame, metres);
the volume spans ``roi`` with ``ceil(size / voxel) + 1`` samples per axis. Each voxel keeps a
weighted mean of truncated projective distances, ``tsdf`` in [-1, 1] (units of ``trunc``,
positive in front of the surface, i.e. towards the cameras), and the summed ``weight`` of the
observations (1 per depth map that saw it, by default).

Integration of a :class:`DepthFrame` (z-depth per pixel, pinhole intrinsics, pose): every voxel
is projected into the image with the OpenCV convention, **pixel centres at integer
coordinates** (pixel ``u`` covers ``[u - 0.5, u + 0.5)``), the depth there is read (bilinear
between the four surrounding pixel centres when all four are valid and agree to within
``trunc``; the nearest pixel otherwise) and ``sdf = depth - z_voxel`` is truncated to
``[-trunc, trunc]``. Voxels more than ``behind`` (at most ``trunc``) behind the observed
surface are left alone (that space is unseen). A short ``behind`` band keeps the votes of a
surface seen from above out of the free space beside the object: with ``behind = trunc`` the
views looking across a box's top call the space just outside its far wall "inside", and the
fused top grows a lip 1-3 mm out over every convex edge (bench/results/fused_footprint.md).
A half-pixel slip here (taking ``floor(u)`` as the nearest pixel, as
some libraries do for pixel-corner conventions) shifts every surface sideways by half a pixel
and biases slanted surfaces; ``tests/armstereo/fusion/test_tsdf.py`` measures that.

The kernel is compiled with numba (``nogil``) and runs over slabs of the x axis on a few Python
threads, like the stereo matcher (no OpenMP pool left spinning afterwards).
"""

from __future__ import annotations

import math
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numba
import numpy as np
from numba import njit

from armstereo.errors import ConfigError

MAX_VOXELS = 200_000_000  # 1.6 GB of tsdf + weight: beyond this, ask for a coarser grid
MIN_CAMERA_Z_M = 1e-3  # voxels closer to the camera plane than this are skipped
INTERP_NEAREST = 0
INTERP_BILINEAR = 1
INTERPOLATIONS = {"nearest": INTERP_NEAREST, "bilinear": INTERP_BILINEAR}
SLABS_PER_THREAD = 4  # x slabs per worker thread: evens out the work between threads


@dataclass(frozen=True)
class Roi:
    """Axis-aligned box in the base frame: ``lo`` and ``hi`` corners (m)."""

    lo: tuple[float, float, float]
    hi: tuple[float, float, float]

    def __post_init__(self) -> None:
        lo, hi = np.asarray(self.lo, float), np.asarray(self.hi, float)
        if lo.shape != (3,) or hi.shape != (3,) or not np.all(np.isfinite(lo)) \
                or not np.all(np.isfinite(hi)) or np.any(hi <= lo):
            raise ConfigError(f"region of interest needs finite corners with min < max on every "
                              f"axis, got lo {self.lo} hi {self.hi}")
        object.__setattr__(self, "lo", tuple(float(v) for v in lo))
        object.__setattr__(self, "hi", tuple(float(v) for v in hi))

    @classmethod
    def parse(cls, text: str) -> Roi:
        """From ``xmin,xmax,ymin,ymax,zmin,zmax`` (m, base frame)."""
        try:
            v = [float(s) for s in text.split(",")]
        except ValueError:
            v = []
        if len(v) != 6 or not all(math.isfinite(x) for x in v) or v[0] >= v[1] \
                or v[2] >= v[3] or v[4] >= v[5]:
            raise ConfigError("--roi must be xmin,xmax,ymin,ymax,zmin,zmax (m) with min < max, "
                              f"not {text!r}")
        return cls((v[0], v[2], v[4]), (v[1], v[3], v[5]))

    def grid_shape(self, voxel: float) -> tuple[int, int, int]:
        """Samples per axis for a voxel edge of ``voxel`` m."""
        size = np.asarray(self.hi) - np.asarray(self.lo)
        n = np.ceil(size / voxel - 1e-9).astype(int) + 1
        return int(n[0]), int(n[1]), int(n[2])

    def contains(self, points: np.ndarray) -> np.ndarray:
        """Boolean (N,) mask of the points (N, 3, base) inside the box."""
        p = np.asarray(points, dtype=float).reshape(-1, 3)
        return np.all((p >= self.lo) & (p <= self.hi), axis=1)

    def corners(self) -> np.ndarray:
        """The 8 corners (8, 3), base frame."""
        lo, hi = np.asarray(self.lo), np.asarray(self.hi)
        return np.array([[(lo, hi)[i][0], (lo, hi)[j][1], (lo, hi)[k][2]]
                         for i in (0, 1) for j in (0, 1) for k in (0, 1)])

    def as_list(self) -> list[float]:
        """``[xmin, xmax, ymin, ymax, zmin, zmax]`` (the --roi order)."""
        return [self.lo[0], self.hi[0], self.lo[1], self.hi[1], self.lo[2], self.hi[2]]

    def __str__(self) -> str:
        return ",".join(f"{v:.4g}" for v in self.as_list())


@dataclass(frozen=True)
class DepthFrame:
    """One depth map to fuse: z-depth (H, W) float32 metres (NaN = none) of a pinhole camera
    with intrinsics ``K`` (3x3, OpenCV: pixel centres at integer coordinates, no distortion)
    at pose ``T_base_camera`` (camera optical frame in base). ``image`` is the matching BGR
    uint8 picture (for colour) or None; ``pair`` and ``label`` say where it came from;
    ``weight`` (H, W) float32 >= 0 is each pixel's observation weight (None: 1 everywhere;
    :mod:`armstereo.fusion.depth_filter` makes it an inverse-variance weight)."""

    depth: np.ndarray
    K: np.ndarray
    T_base_camera: np.ndarray
    image: np.ndarray | None = None
    pair: int = 0
    label: str = ""
    weight: np.ndarray | None = None

    def __post_init__(self) -> None:
        d = np.asarray(self.depth)
        if d.ndim != 2 or d.dtype.kind != "f":
            raise ConfigError(f"depth must be a 2D float array, got {d.dtype} {d.shape}")
        K = np.asarray(self.K, dtype=float)
        if K.shape != (3, 3) or K[0, 0] <= 0 or K[1, 1] <= 0 or K[2, 2] != 1.0 or K[0, 1] \
                or K[1, 0] or K[2, 0] or K[2, 1]:
            raise ConfigError(f"K must be a 3x3 pinhole matrix without skew, got {K.tolist()}")
        T = _check_rigid(self.T_base_camera, "T_base_camera")
        if self.image is not None and np.shape(self.image)[:2] != d.shape:
            raise ConfigError(f"image {np.shape(self.image)} and depth {d.shape} differ in size")
        if self.weight is not None:
            w = np.ascontiguousarray(self.weight, dtype=np.float32)
            if w.shape != d.shape or not np.all(np.isfinite(w)) or np.any(w < 0):
                raise ConfigError(f"weight must be a finite, non-negative {d.shape} map, got "
                                  f"{w.dtype} {w.shape}")
            object.__setattr__(self, "weight", w)
        object.__setattr__(self, "depth", np.ascontiguousarray(d, dtype=np.float32))
        object.__setattr__(self, "K", K)
        object.__setattr__(self, "T_base_camera", T)

    @property
    def T_camera_base(self) -> np.ndarray:
        R, t = self.T_base_camera[:3, :3], self.T_base_camera[:3, 3]
        out = np.eye(4)
        out[:3, :3] = R.T
        out[:3, 3] = -R.T @ t
        return out

    def project(self, points_base: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(u, v, z) of base-frame points (N, 3): pixel coordinates (OpenCV convention) and
        z-depth in this camera (m)."""
        T = self.T_camera_base
        p = rotate(T[:3, :3], np.asarray(points_base, dtype=float).reshape(-1, 3)) + T[:3, 3]
        z = p[:, 2]
        with np.errstate(divide="ignore", invalid="ignore"):
            u = self.K[0, 0] * p[:, 0] / z + self.K[0, 2]
            v = self.K[1, 1] * p[:, 1] / z + self.K[1, 2]
        return u, v, z


def rotate(R: np.ndarray, points: np.ndarray) -> np.ndarray:
    """``points @ R.T`` for (N, 3) points, without BLAS: numpy hands this product to a
    threaded BLAS, which on a busy 2-core machine measured 35-70x slower than this loop
    (0.4-0.8 s against 25 ms for 400 k points)."""
    return np.einsum("ij,nj->ni", R, points)


def _check_rigid(T, name: str) -> np.ndarray:
    """A 4x4 rigid transform, or ConfigError (the reshape adds ``transforms.as_rigid``)."""
    T = np.asarray(T, dtype=float)
    if T.shape != (4, 4) or not np.all(np.isfinite(T)):
        raise ConfigError(f"{name} must be a finite 4x4 transform, got shape {T.shape}")
    R = T[:3, :3]
    if not np.allclose(R @ R.T, np.eye(3), atol=1e-6) or np.linalg.det(R) <= 0 \
            or not np.allclose(T[3], (0, 0, 0, 1)):
        raise ConfigError(f"{name} is not a rigid transform")
    return T


class TsdfVolume:
    """Dense TSDF over ``roi`` with voxel edge ``voxel`` and truncation ``trunc`` (m).

    ``tsdf`` (nx, ny, nz) float32 in [-1, 1], 1 where unobserved; ``weight`` (nx, ny, nz)
    float32, 0 where unobserved. ``interpolation`` is ``bilinear`` (default) or ``nearest``;
    ``behind`` (m, in [voxel, trunc], None = ``trunc``) how far behind an observed surface
    voxels are updated.
    """

    def __init__(self, roi: Roi, voxel: float, trunc: float, *,
                 interpolation: str = "bilinear", threads: int | None = None,
                 behind: float | None = None):
        if not (math.isfinite(voxel) and voxel > 0):
            raise ConfigError(f"--voxel must be a positive length in metres, got {voxel}")
        if not (math.isfinite(trunc) and trunc >= voxel):
            raise ConfigError(f"--trunc must be at least one voxel ({voxel} m), got {trunc}")
        behind = trunc if behind is None else behind
        if not (math.isfinite(behind) and voxel <= behind <= trunc):
            raise ConfigError(f"the band behind the surface must be in [voxel = {voxel}, "
                              f"trunc = {trunc}] m, got {behind}")
        if interpolation not in INTERPOLATIONS:
            raise ConfigError(f"interpolation must be one of {', '.join(INTERPOLATIONS)}, "
                              f"got {interpolation!r}")
        shape = roi.grid_shape(voxel)
        n = shape[0] * shape[1] * shape[2]
        if n > MAX_VOXELS:
            raise ConfigError(f"the region of interest {roi} at {voxel * 1000:g} mm voxels needs "
                              f"{n / 1e6:.0f} M voxels (limit {MAX_VOXELS / 1e6:.0f} M); "
                              "use a smaller --roi or a larger --voxel")
        self.roi, self.voxel, self.trunc = roi, float(voxel), float(trunc)
        self.behind = float(behind)
        self.interpolation = interpolation
        self.threads = max(1, threads or numba.get_num_threads())
        self.origin = np.asarray(roi.lo, dtype=np.float64)
        self.tsdf = np.ones(shape, dtype=np.float32)
        self.weight = np.zeros(shape, dtype=np.float32)

    @property
    def shape(self) -> tuple[int, int, int]:
        return self.tsdf.shape

    @property
    def voxel_count(self) -> int:
        return int(self.tsdf.size)

    @property
    def memory_bytes(self) -> int:
        return int(self.tsdf.nbytes + self.weight.nbytes)

    def integrate(self, frame: DepthFrame, weight: float = 1.0) -> int:
        """Fuse one depth map, each pixel with ``weight`` times its ``frame.weight`` (pixels
        of weight 0 are skipped); returns how many voxels it updated."""
        if not (math.isfinite(weight) and weight > 0):
            raise ConfigError(f"observation weight must be > 0, got {weight}")
        T = frame.T_camera_base
        R = np.ascontiguousarray(T[:3, :3])
        t = np.ascontiguousarray(T[:3, 3])
        K = frame.K
        per_pixel = frame.weight is not None
        wmap = frame.weight if per_pixel else np.ones((1, 1), np.float32)
        args = (self.tsdf, self.weight, self.origin, self.voxel, R, t, K[0, 0], K[1, 1],
                K[0, 2], K[1, 2], frame.depth, wmap, per_pixel, self.trunc, self.behind,
                float(weight), INTERPOLATIONS[self.interpolation])
        nx = self.shape[0]
        if self.threads == 1:
            return int(_integrate_slab(0, nx, *args))
        edges = np.linspace(0, nx, self.threads * SLABS_PER_THREAD + 1).astype(int)
        with ThreadPoolExecutor(self.threads) as pool:
            counts = pool.map(lambda ab: _integrate_slab(ab[0], ab[1], *args),
                              zip(edges[:-1], edges[1:], strict=True))
            return int(sum(counts))

    def observed(self, min_weight: float) -> np.ndarray:
        """Boolean mask of the voxels with at least ``min_weight`` of observations."""
        return self.weight >= min_weight

    def voxel_points(self, index: np.ndarray) -> np.ndarray:
        """Base-frame positions (N, 3) of voxel indices (N, 3) (fractional indices allowed)."""
        return self.origin + np.asarray(index, dtype=float) * self.voxel


@njit(nogil=True, cache=True)
def _sample_depth(depth, u, v, trunc, interp):
    """Depth at pixel position (u, v) (pixel centres at integers); NaN where unknown."""
    H, W = depth.shape
    nan = np.float32(np.nan)
    if not (u > -0.5 and v > -0.5 and u < W - 0.5 and v < H - 0.5):
        return nan
    iu = int(math.floor(u + 0.5))
    iv = int(math.floor(v + 0.5))
    d = depth[iv, iu]
    if interp != INTERP_BILINEAR:
        return d
    u0 = int(math.floor(u))
    v0 = int(math.floor(v))
    if u0 < 0 or v0 < 0 or u0 + 1 >= W or v0 + 1 >= H:
        return d
    d00 = depth[v0, u0]
    d01 = depth[v0, u0 + 1]
    d10 = depth[v0 + 1, u0]
    d11 = depth[v0 + 1, u0 + 1]
    if not (d00 > 0.0 and d01 > 0.0 and d10 > 0.0 and d11 > 0.0):  # a hole (NaN) nearby
        return d
    lo = min(min(d00, d01), min(d10, d11))
    hi = max(max(d00, d01), max(d10, d11))
    if hi - lo > trunc:  # a depth edge: blending would invent a surface between the two
        return d
    fu = u - u0
    fv = v - v0
    return ((d00 * (1.0 - fu) + d01 * fu) * (1.0 - fv)
            + (d10 * (1.0 - fu) + d11 * fu) * fv)


@njit(nogil=True, cache=True)
def _integrate_slab(i0, i1, tsdf, weight, origin, voxel, R, t, fx, fy, cx, cy, depth, wmap,
                    per_pixel, trunc, behind, w_frame, interp):
    """Fuse ``depth`` into voxels with x index in [i0, i1); returns the number updated.
    ``wmap`` is the per-pixel weight (read at the nearest pixel) when ``per_pixel``."""
    ny = tsdf.shape[1]
    nz = tsdf.shape[2]
    count = 0
    for i in range(i0, i1):
        x = origin[0] + i * voxel
        for j in range(ny):
            y = origin[1] + j * voxel
            ax = R[0, 0] * x + R[0, 1] * y + t[0]
            ay = R[1, 0] * x + R[1, 1] * y + t[1]
            az = R[2, 0] * x + R[2, 1] * y + t[2]
            for k in range(nz):
                z = origin[2] + k * voxel
                pz = az + R[2, 2] * z
                if pz <= MIN_CAMERA_Z_M:
                    continue
                u = fx * (ax + R[0, 2] * z) / pz + cx
                v = fy * (ay + R[1, 2] * z) / pz + cy
                d = _sample_depth(depth, u, v, trunc, interp)
                if not (d > 0.0):
                    continue
                sdf = d - pz
                if sdf < -behind:
                    continue
                w_obs = w_frame
                if per_pixel:
                    w_obs *= wmap[int(math.floor(v + 0.5)), int(math.floor(u + 0.5))]
                    if not (w_obs > 0.0):
                        continue
                val = min(1.0, sdf / trunc)
                w_old = weight[i, j, k]
                w_new = w_old + w_obs
                tsdf[i, j, k] = (tsdf[i, j, k] * w_old + val * w_obs) / w_new
                weight[i, j, k] = w_new
                count += 1
    return count
