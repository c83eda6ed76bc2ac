"""Analytic ray-cast scenes for the mock camera, in the controller's ``base`` frame (metres).

A :class:`Scene` is a list of primitives (finite rectangles, boxes rotated about z, upright
capped cylinders, spheres). Each carries a :class:`Texture` defined on 3D *base* coordinates,
so the same surface point has the same colour from every viewpoint (what stereo assumes). The
textures are band-limited sums of sinusoids squashed for contrast: blobs of a few millimetres,
never per-pixel white noise, which breaks the Birchfield-Tomasi cost
(docs/birchfield-tomasi.md §9.1).
Lighting is Lambertian under a light fixed in the base frame, so it does not depend on the
viewpoint either, except on glossy primitives (``specular > 0``, Blinn-Phong): their highlights
move with the camera, as on real varnish, ceramics and plastic. A :class:`PhotoTexture` maps a
photograph onto a primitive's surface coordinates instead (see ``drivers/mock/desk.py``).

:meth:`Scene.render` casts a ray through every pixel centre (numpy, vectorised) through the
camera's lens model, including OpenCV distortion, plus several rays per pixel where one would
alias (silhouettes, creases, grazing surfaces), and returns a BGR image and the exact z-depth
at each pixel centre. The table top is the plane z = 0 (the arm stands on it), objects sit around
:data:`SCENE_CENTER`.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from collections.abc import Sequence
from dataclasses import dataclass
from typing import NamedTuple

import cv2
import numpy as np

from armstereo.camera_model import Intrinsics
from armstereo.errors import ConfigError
from armstereo.evaluation.scene_truth import SceneTruth, TruthPrimitive
from armstereo.transforms import as_rigid, invert, make_T, rot_z

# Centre of the default table scene, base-frame (x, y) in metres. At their ready configuration
# UR arms hold the flange in front of the base, looking straight down (UR5e: flange at
# (-0.492, -0.133, 0.488) m, checked against an independent DH computation). This point is
# 0.47 m from the base axis: UR5e, UR5, UR10e and UR16e put the camera 0.55 m above it with
# joints 0.1 rad inside their limits and sigma_min ~ 0.2, and keep that for camera baselines of
# +-0.3 m along the camera's x axis (base y). The UR3e (0.5 m reach) cannot: use a lower height.
SCENE_CENTER = (-0.45, -0.13)

T_MIN = 1e-9  # rays start this far from their origin (m), so a surface never hits itself
MAX_SUPERSAMPLE = 4
DEFAULT_LIGHT = (0.3, 0.2, 1.0)  # direction towards the light, base frame
DEFAULT_AMBIENT = 0.45
_UNDISTORT_TOL_PX = 0.01  # rays whose re-distorted pixel misses by more are dropped
EDGE_STEP = 8.0  # grey levels between neighbouring pixels that mark a hard texture edge


class Texture:
    """Band-limited solid texture: colour as a function of a 3D point (metres, base frame).

    ``s(p) = sum_k sin(w_k . (p - anchor) + phi_k)`` over ``components`` directions spread
    evenly over the sphere (randomly rotated, so every surface orientation sees an isotropic
    pattern) with wavelengths log-spaced in [``min_wavelength``, ``max_wavelength``] and
    shuffled; ``s`` is normalised and squashed by a sigmoid of gain ``contrast`` into a blend of
    ``dark_bgr`` and ``light_bgr``. Deterministic for a given ``seed``. Features (half a
    wavelength) are ``min_wavelength / 2`` and up.
    """

    def __init__(self, dark_bgr: Sequence[float], light_bgr: Sequence[float], *,
                 min_wavelength: float = 0.008, max_wavelength: float = 0.022,
                 components: int = 16, contrast: float = 2.0, seed: int = 0):
        if not 0 < min_wavelength <= max_wavelength:
            raise ConfigError(f"texture wavelengths must satisfy 0 < min <= max, got "
                              f"{min_wavelength}, {max_wavelength}")
        if components < 1:
            raise ConfigError(f"texture needs at least one component, got {components}")
        rng = np.random.default_rng(seed)
        dirs = _fibonacci_sphere(components) @ _random_rotation(rng).T
        lam = np.exp(np.linspace(math.log(min_wavelength), math.log(max_wavelength),
                                 components))
        rng.shuffle(lam)
        self.dark = np.asarray(dark_bgr, dtype=np.float32).reshape(3, 1)
        self.light = np.asarray(light_bgr, dtype=np.float32).reshape(3, 1)
        self.min_wavelength = float(min_wavelength)
        self._omega = (dirs * (2 * np.pi / lam)[:, None]).astype(np.float32)  # (K, 3)
        self._phase = rng.uniform(0, 2 * np.pi, (components, 1)).astype(np.float32)
        self._gain = np.full(components, contrast * math.sqrt(2.0 / components), np.float32)

    def albedo(self, points: np.ndarray, anchor: np.ndarray) -> np.ndarray:
        """BGR (3, N) float32 in 0..255 at ``points`` (3, N), base frame.

        ``anchor`` (3,) is a fixed point near the surface; subtracting it keeps float32 phases
        small (the texture stays a function of the world point).
        """
        p = (np.asarray(points, dtype=np.float64) - np.reshape(anchor, (3, 1)))
        arg = np.einsum("kj,jn->kn", self._omega, p.astype(np.float32))  # no BLAS threads
        arg += self._phase
        np.sin(arg, out=arg)
        x = self._gain @ arg
        v = 0.5 + 0.5 * x / np.sqrt(1.0 + x * x)  # smooth sigmoid: contrast without aliasing
        return self.dark + v * (self.light - self.dark)


def _fibonacci_sphere(n: int) -> np.ndarray:
    """``n`` unit vectors (n, 3) spread evenly over the sphere (golden-angle spiral)."""
    k = np.arange(n) + 0.5
    z = 1.0 - 2.0 * k / n
    phi = k * math.pi * (3.0 - math.sqrt(5.0))
    r = np.sqrt(1.0 - z * z)
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)


def _random_rotation(rng: np.random.Generator) -> np.ndarray:
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    q = q * np.sign(np.diag(r))
    return q if np.linalg.det(q) > 0 else -q


class Primitive(ABC):
    """A closed or planar surface with a local frame ``T_base_local`` and a texture."""

    def __init__(self, T_base_local: np.ndarray, texture: Texture, name: str):
        self.T_base_local = np.asarray(T_base_local, dtype=float)
        self.T_local_base = invert(self.T_base_local)
        self.texture = texture
        self.name = name
        self.specular = 0.0  # Blinn-Phong highlight strength (0 = matte), share of full white
        self.shininess = 40.0  # Blinn-Phong exponent: larger = smaller, sharper highlights
        # Rays per pixel side where this primitive's texture has a hard edge (a printed
        # calibration board): 0 = band-limited texture, no edges to anti-alias.
        self.edge_supersample = 0

    def glossy(self, specular: float, shininess: float = 40.0) -> Primitive:
        """Make the surface glossy (highlights that move with the viewpoint); returns self."""
        if not (0.0 <= specular <= 1.0 and shininess > 0):
            raise ConfigError(f"{self.name}: specular must be in [0, 1] and shininess > 0, got "
                              f"{specular}, {shininess}")
        self.specular, self.shininess = float(specular), float(shininess)
        return self

    def albedo(self, points_base: np.ndarray) -> np.ndarray:
        """BGR (3, N) float32 of the texture at surface points (3, N), base frame."""
        if isinstance(self.texture, SurfaceTexture):
            dt = np.asarray(points_base).dtype
            R, t = self.T_local_base[:3, :3].astype(dt), self.T_local_base[:3, 3:].astype(dt)
            p_local = np.einsum("ij,jn->in", R, points_base) + t
            return self.texture.sample(*self.surface_coords(p_local))
        return self.texture.albedo(points_base, self.T_base_local[:3, 3])

    def surface_coords(self, p_local: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Coordinates (s, t) in metres along the surface of local points (3, N), for
        photographs: a rectangle's (x, y), a box face's two in-plane axes, a cylinder's arc
        length and height (its caps: x, y), a sphere's longitude and latitude arcs."""
        return p_local[0], p_local[1]

    @abstractmethod
    def _hit_local(self, o: np.ndarray, dx, dy, dz) -> np.ndarray:
        """Ray parameter of the first hit (inf = miss) for origin ``o`` and direction components
        in the local frame (arrays of one shape)."""

    @abstractmethod
    def _normal_local(self, p: np.ndarray) -> np.ndarray:
        """Outward unit normals (3, N) (or (3, 1) if constant) at local points (3, N)."""

    @abstractmethod
    def _corners_local(self) -> np.ndarray:
        """(K, 3) points whose convex hull contains the primitive (local frame)."""

    def hit(self, T_base_ray: np.ndarray, dx, dy, dz) -> np.ndarray:
        """Ray parameter t of the first hit for rays ``o + t d`` given in frame ``ray``.

        ``T_base_ray`` places the rays' frame in base; ``o`` is its origin and ``d`` the
        direction components (arrays or scalars that broadcast). inf where the ray misses.
        """
        T = self.T_local_base @ T_base_ray
        dtype = np.result_type(dx, dy, dz)  # float32 rays (rendering) stay float32
        R, o = T[:3, :3].astype(dtype), T[:3, 3].astype(dtype)
        lx = R[0, 0] * dx + R[0, 1] * dy + R[0, 2] * dz
        ly = R[1, 0] * dx + R[1, 1] * dy + R[1, 2] * dz
        lz = R[2, 0] * dx + R[2, 1] * dy + R[2, 2] * dz
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            return self._hit_local(o, lx, ly, lz)

    def normals(self, points_base: np.ndarray) -> np.ndarray:
        """Outward unit normals (3, N) (or (3, 1) if constant), base frame, at surface points
        (3, N) in base."""
        dt = np.asarray(points_base).dtype
        R, t = self.T_local_base[:3, :3].astype(dt), self.T_local_base[:3, 3:].astype(dt)
        p_local = np.einsum("ij,jn->in", R, points_base) + t
        n = self._normal_local(p_local).astype(dt)
        return np.einsum("ij,jn->in", self.T_base_local[:3, :3].astype(dt), n)

    def corners_base(self) -> np.ndarray:
        """Points (K, 3) in base whose convex hull contains the primitive."""
        c = self._corners_local()
        return c @ self.T_base_local[:3, :3].T + self.T_base_local[:3, 3]

    @abstractmethod
    def _truth_dims(self) -> tuple[str, tuple[float, ...]]:
        """(kind, dims) as :mod:`armstereo.evaluation.scene_truth` describes them."""

    def truth(self) -> TruthPrimitive:
        """This primitive's exact geometry, for scoring reconstructions against it."""
        kind, dims = self._truth_dims()
        return TruthPrimitive(self.name, kind, self.T_base_local.copy(), dims)


def _miss_where(t: np.ndarray, bad: np.ndarray) -> np.ndarray:
    return np.where(bad | ~(t > T_MIN), np.inf, t)


class Rectangle(Primitive):
    """Finite rectangle ``|x| <= half_x, |y| <= half_y`` in the local z = 0 plane.

    Its normal is local +z; it is visible from both sides.
    """

    def __init__(self, T_base_local: np.ndarray, half_x: float, half_y: float,
                 texture: Texture, name: str = "rectangle"):
        super().__init__(T_base_local, texture, name)
        if half_x <= 0 or half_y <= 0:
            raise ConfigError(f"{name}: half sizes must be positive, got {half_x}, {half_y}")
        self.half_x, self.half_y = float(half_x), float(half_y)

    def _hit_local(self, o, dx, dy, dz):
        t = -o[2] / dz
        x = o[0] + t * dx
        y = o[1] + t * dy
        return _miss_where(t, (np.abs(x) > self.half_x) | (np.abs(y) > self.half_y))

    def _normal_local(self, p):
        return np.array([[0.0], [0.0], [1.0]])

    def normals(self, points_base: np.ndarray) -> np.ndarray:
        return self.T_base_local[:3, 2:3].astype(np.asarray(points_base).dtype)

    def _truth_dims(self):
        return "rectangle", (self.half_x, self.half_y)

    def _corners_local(self):
        hx, hy = self.half_x, self.half_y
        return np.array([[-hx, -hy, 0], [hx, -hy, 0], [hx, hy, 0], [-hx, hy, 0]], dtype=float)


class Box(Primitive):
    """Box of ``size`` (sx, sy, sz) centred at ``center`` (base), rotated ``yaw`` rad about z."""

    def __init__(self, center: Sequence[float], size: Sequence[float], texture: Texture, *,
                 yaw: float = 0.0, name: str = "box"):
        half = np.asarray(size, dtype=float).reshape(3) / 2
        if np.any(half <= 0):
            raise ConfigError(f"{name}: box size must be positive, got {tuple(size)}")
        super().__init__(make_T(rot_z(yaw), center), texture, name)
        self.half = half

    def _hit_local(self, o, dx, dy, dz):
        t_near = t_far = None
        for axis, d in enumerate((dx, dy, dz)):
            inv = 1.0 / d
            h = float(self.half[axis])
            t1 = (-h - o[axis]) * inv
            t2 = (h - o[axis]) * inv
            lo, hi = np.minimum(t1, t2), np.maximum(t1, t2)
            t_near = lo if t_near is None else np.maximum(t_near, lo)
            t_far = hi if t_far is None else np.minimum(t_far, hi)
        # From outside the first hit is t_near; a ray starting inside leaves through t_far.
        t = np.where(t_near > T_MIN, t_near, t_far)
        return _miss_where(t, ~(t_far >= t_near))

    def _normal_local(self, p):
        k = np.argmax(np.abs(p) / self.half[:, None], axis=0)
        n = np.zeros_like(p)
        cols = np.arange(p.shape[1])
        n[k, cols] = np.sign(p[k, cols])
        return n

    def surface_coords(self, p_local):
        k = np.argmax(np.abs(p_local) / self.half[:, None].astype(p_local.dtype), axis=0)
        s = np.where(k == 0, p_local[1], p_local[0])
        t = np.where(k == 2, p_local[1], p_local[2])
        return s, t

    def _truth_dims(self):
        return "box", tuple(float(v) for v in 2 * self.half)

    def _corners_local(self):
        s = np.array([[i, j, k] for i in (-1, 1) for j in (-1, 1) for k in (-1, 1)], dtype=float)
        return s * self.half


class Cylinder(Primitive):
    """Upright capped cylinder: axis along base z through ``center_xy``, from ``z0`` up
    ``height`` metres, ``radius`` metres."""

    def __init__(self, center_xy: Sequence[float], radius: float, height: float,
                 texture: Texture, *, z0: float = 0.0, name: str = "cylinder"):
        if radius <= 0 or height <= 0:
            raise ConfigError(f"{name}: radius and height must be positive, got {radius}, "
                              f"{height}")
        cx, cy = (float(v) for v in center_xy)
        super().__init__(make_T(np.eye(3), (cx, cy, z0)), texture, name)
        self.radius, self.height = float(radius), float(height)

    def _hit_local(self, o, dx, dy, dz):
        r, h = self.radius, self.height
        a = dx * dx + dy * dy
        b = 2.0 * (o[0] * dx + o[1] * dy)
        c = o[0] ** 2 + o[1] ** 2 - r * r
        disc = b * b - 4.0 * a * c
        t_side = (-b - np.sqrt(disc)) / (2.0 * a)
        z = o[2] + t_side * dz
        t = _miss_where(t_side, ~((disc >= 0) & (z >= 0) & (z <= h)))
        for zc in (0.0, h):
            t_cap = (zc - o[2]) / dz
            x = o[0] + t_cap * dx
            y = o[1] + t_cap * dy
            t = np.minimum(t, _miss_where(t_cap, ~(x * x + y * y <= r * r)))
        return t

    def _normal_local(self, p):
        rho = np.hypot(p[0], p[1])
        # The surface nearest to the point decides (side wall or one of the caps).
        d_side = np.abs(self.radius - rho)
        d_top, d_bottom = np.abs(p[2] - self.height), np.abs(p[2])
        side = d_side < np.minimum(d_top, d_bottom)
        safe = np.maximum(rho, 1e-12)
        return np.stack([np.where(side, p[0] / safe, 0.0), np.where(side, p[1] / safe, 0.0),
                         np.where(side, 0.0, np.where(d_top <= d_bottom, 1.0, -1.0))])

    def _truth_dims(self):
        return "cylinder", (self.radius, self.height)

    def surface_coords(self, p_local):
        rho = np.hypot(p_local[0], p_local[1])
        side = np.abs(self.radius - rho) < np.minimum(np.abs(p_local[2] - self.height),
                                                       np.abs(p_local[2]))
        arc = self.radius * np.arctan2(p_local[1], p_local[0])
        return np.where(side, arc, p_local[0]), np.where(side, p_local[2], p_local[1])

    def _corners_local(self):
        r, h = self.radius, self.height
        return np.array([[i * r, j * r, k] for i in (-1, 1) for j in (-1, 1) for k in (0, h)],
                        dtype=float)


class Sphere(Primitive):
    """Sphere of ``radius`` metres centred at ``center`` (base)."""

    def __init__(self, center: Sequence[float], radius: float, texture: Texture, *,
                 name: str = "sphere"):
        if radius <= 0:
            raise ConfigError(f"{name}: radius must be positive, got {radius}")
        super().__init__(make_T(np.eye(3), center), texture, name)
        self.radius = float(radius)

    def _hit_local(self, o, dx, dy, dz):
        a = dx * dx + dy * dy + dz * dz
        b = 2.0 * (o[0] * dx + o[1] * dy + o[2] * dz)
        c = o @ o - o.dtype.type(self.radius ** 2)
        disc = b * b - 4.0 * a * c
        sq = np.sqrt(disc)
        t_near = (-b - sq) / (2.0 * a)
        t = np.where(t_near > T_MIN, t_near, (-b + sq) / (2.0 * a))
        return _miss_where(t, ~(disc >= 0))

    def _normal_local(self, p):
        return p / np.linalg.norm(p, axis=0, keepdims=True)

    def _truth_dims(self):
        return "sphere", (self.radius,)

    def surface_coords(self, p_local):
        r = self.radius
        lat = np.arcsin(np.clip(p_local[2] / r, -1.0, 1.0))
        return r * np.arctan2(p_local[1], p_local[0]), r * lat

    def _corners_local(self):
        r = self.radius
        return np.array([[i, j, k] for i in (-r, r) for j in (-r, r) for k in (-r, r)])


@dataclass
class _RayGrid:
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


_RAY_CACHE: dict[tuple, _RayGrid] = {}
_RAY_CACHE_SIZE = 8


def _ray_grid(intr: Intrinsics) -> _RayGrid:
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
    grid = _RayGrid(xn, yn, jac,
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


class Scene:
    """A set of primitives in the base frame, lit by a directional light fixed in base.

    ``light_dir`` points towards the light; shading is ``ambient + (1 - ambient) * |n . l|``
    (two-sided, so planar targets facing any way are lit). ``background_bgr`` fills pixels whose
    ray hits nothing (their depth is NaN).
    """

    def __init__(self, primitives: Sequence[Primitive], *,
                 light_dir: Sequence[float] = DEFAULT_LIGHT, ambient: float = DEFAULT_AMBIENT,
                 background_bgr: Sequence[float] = (0.0, 0.0, 0.0),
                 support: str | None = None):
        if not primitives:
            raise ConfigError("a scene needs at least one primitive")
        if not 0.0 <= ambient <= 1.0:
            raise ConfigError(f"ambient must be in [0, 1], got {ambient}")
        light = np.asarray(light_dir, dtype=float).reshape(3)
        self.primitives = tuple(primitives)
        self.light_dir = light / np.linalg.norm(light)
        self.ambient = float(ambient)
        self.background = np.asarray(background_bgr, dtype=np.float32).reshape(3)
        self.support = support  # name of the primitive objects stand on (the table top)

    def truth(self) -> SceneTruth:
        """The exact geometry of every primitive, for scoring reconstructions (base frame)."""
        return SceneTruth([p.truth() for p in self.primitives], self.support)

    def intersect(self, origin: np.ndarray, directions: np.ndarray):
        """First hits of rays ``origin + t * directions[i]`` (base frame, float64).

        Returns ``(t, index)``: t (N,) in units of the direction's length (inf = miss) and the
        index (N,) into :attr:`primitives` (-1 = miss).
        """
        d = np.asarray(directions, dtype=float).reshape(-1, 3)
        T = make_T(np.eye(3), np.asarray(origin, dtype=float).reshape(3))
        t_best = np.full(len(d), np.inf)
        idx = np.full(len(d), -1)
        for i, prim in enumerate(self.primitives):
            t = prim.hit(T, d[:, 0], d[:, 1], d[:, 2])
            better = t < t_best
            t_best[better] = t[better]
            idx[better] = i
        return t_best, idx

    def surface_color(self, points: np.ndarray, index: np.ndarray) -> np.ndarray:
        """Shaded BGR (N, 3) float32 in 0..255 of surface points (N, 3, base) on primitives
        ``index`` (N,); the colour does not depend on the viewpoint."""
        points = np.asarray(points, dtype=float).reshape(-1, 3)
        index = np.asarray(index).reshape(-1)
        out = np.empty((len(points), 3), dtype=np.float32)
        for i in np.unique(index):
            sel = index == i
            prim = self.primitives[int(i)]
            out[sel] = self._color(prim, points[sel].T, prim.normals(points[sel].T)).T
        return out

    def _color(self, prim: Primitive, p: np.ndarray, n: np.ndarray,
               eye: np.ndarray | None = None) -> np.ndarray:
        """Shaded BGR (3, N) float32 of points (3, N) with normals (3, N) on ``prim``; with
        the camera centre ``eye`` (base) a glossy primitive also gets its highlights."""
        cos = np.abs(np.einsum("i,in->n", self.light_dir, n))
        shade = self.ambient + (1.0 - self.ambient) * cos
        color = prim.albedo(p) * shade.astype(np.float32)
        if prim.specular > 0 and eye is not None:
            color = color + _highlight(prim, p, n, self.light_dir, eye)
        return color

    def render(self, T_base_camera: np.ndarray, intrinsics: Intrinsics, *,
               supersample: int = 2) -> tuple[np.ndarray, np.ndarray]:
        """Image and ground truth seen by a camera at ``T_base_camera`` (camera_optical in base).

        Each pixel is shaded at its centre; pixels on silhouettes, creases and grazing surfaces
        (where a single sample aliases) are re-rendered as the mean of ``supersample`` x
        ``supersample`` rays. The textures are band-limited, so flat interiors need no more.
        Depth is the exact z-depth (metres, float32) of the ray through each pixel centre, NaN
        where nothing is hit. With non-zero ``intrinsics.dist`` the rays go through the lens
        distortion, so the image is distorted like a real camera's.
        Returns ``(bgr uint8 (H, W, 3), depth float32 (H, W))``.
        """
        T = _check_pose(T_base_camera)
        s = int(supersample)
        if not 1 <= s <= MAX_SUPERSAMPLE or s != supersample:
            raise ConfigError(f"supersample must be an integer in 1..{MAX_SUPERSAMPLE}, "
                              f"got {supersample}")
        grid = _ray_grid(intrinsics)
        t, idx, blocks = self._cast(T, grid)
        img, normals = self._shade_grid(T, grid, t, idx, blocks)
        edges = self._sharp_edge_pixels(img, idx)
        if s > 1:
            rows, cols = np.nonzero(_aliasing_pixels(idx, normals, grid) & ~edges)
            img[rows, cols] = self._supersample(T, *grid.subpixel_rays(rows, cols, s), s)
        if edges.any():
            s_edge = max(p.edge_supersample for p in self.primitives)
            rows, cols = np.nonzero(edges)
            img[rows, cols] = self._supersample(T, *grid.subpixel_rays(rows, cols, s_edge),
                                                s_edge)
        bgr = np.clip(np.rint(img), 0, 255).astype(np.uint8)
        depth = np.where(np.isfinite(t), t, np.nan).astype(np.float32)
        return bgr, depth

    def _sharp_edge_pixels(self, img: np.ndarray, idx: np.ndarray) -> np.ndarray:
        """Boolean (H, W) mask of pixels near a hard texture edge of a primitive with
        ``edge_supersample``: their colour differs from a 4-neighbour's by more than
        EDGE_STEP grey levels. A centre sample there would put the edge on the pixel grid
        (biasing the corners a detector finds by up to half a pixel)."""
        sharp = [i for i, p in enumerate(self.primitives) if p.edge_supersample > 1]
        if not sharp:
            return np.zeros(idx.shape, dtype=bool)
        on = np.isin(idx, sharp)
        if not on.any():
            return on
        grey = img.mean(axis=2)
        # An edge crossing a pixel always separates it from one of its 4-neighbours (the one
        # along the edge normal's larger component), so the cross neighbourhood suffices.
        k = cv2.getStructuringElement(cv2.MORPH_CROSS, (3, 3))
        spread = cv2.dilate(grey, k) - cv2.erode(grey, k)
        return on & (spread > EDGE_STEP)

    def _cast(self, T_base_camera: np.ndarray, grid: _RayGrid):
        """z-buffer over the ray grid: ray parameter (= z-depth), primitive index, and the grid
        block each primitive can cover."""
        shape = grid.xn.shape
        t_best = np.full(shape, np.inf, dtype=np.float32)
        idx = np.full(shape, -1, dtype=np.int16)
        T_camera_base = invert(T_base_camera)
        blocks = []
        for i, prim in enumerate(self.primitives):
            block = _footprint(prim, T_camera_base, grid)
            blocks.append(block)
            if block is None:
                continue
            t = prim.hit(T_base_camera, grid.xn[block], grid.yn[block], np.float32(1.0))
            tb, ib = t_best[block], idx[block]
            better = t < tb
            tb[better] = t[better]
            ib[better] = i
        return t_best, idx, blocks

    def _shade_grid(self, T: np.ndarray, grid: _RayGrid, t: np.ndarray, idx: np.ndarray,
                    blocks: list):
        """Colours (H, W, 3) and unit normals (H, W, 3; zero on misses) of the grid's hits."""
        img = np.empty(t.shape + (3,), dtype=np.float32)
        img[...] = self.background
        normals = np.zeros(t.shape + (3,), dtype=np.float32)
        for i, (prim, block) in enumerate(zip(self.primitives, blocks, strict=True)):
            if block is None:
                continue
            m = idx[block] == i
            if not m.any():
                continue
            color, n = self._shade_rays(prim, T, grid.xn[block][m], grid.yn[block][m],
                                        t[block][m])
            img[block][m] = color.T
            normals[block][m] = np.broadcast_to(n, color.shape).T
        return img, normals

    def _shade_rays(self, prim: Primitive, T: np.ndarray, xn, yn, t):
        """Colours (3, N) and normals (3, N or 1) where camera rays (xn, yn, 1) hit ``prim``
        at z-depth ``t`` (float32 arrays)."""
        R, o = T[:3, :3].astype(np.float32), T[:3, 3:].astype(np.float32)
        p = o + np.einsum("ij,jn->in", R, np.stack([xn * t, yn * t, t]))  # (3, N) base
        n = prim.normals(p)
        return self._color(prim, p, n, T[:3, 3]), n

    def _supersample(self, T: np.ndarray, xn: np.ndarray, yn: np.ndarray, s: int):
        """Mean colour (M, 3) of camera rays (xn, yn, 1) taken s * s per pixel."""
        t_best = np.full(xn.shape, np.inf, dtype=np.float32)
        idx = np.full(xn.shape, -1, dtype=np.int16)
        T_camera_base = invert(T)
        for i, prim in enumerate(self.primitives):
            cand = np.flatnonzero(_in_footprint(prim, T_camera_base, xn, yn))
            t = prim.hit(T, xn[cand], yn[cand], np.float32(1.0))
            better = t < t_best[cand]
            t_best[cand[better]] = t[better]
            idx[cand[better]] = i
        colors = np.empty(xn.shape + (3,), dtype=np.float32)
        colors[...] = self.background
        for i, prim in enumerate(self.primitives):
            sel = np.flatnonzero(idx == i)
            if sel.size:
                colors[sel] = self._shade_rays(prim, T, xn[sel], yn[sel], t_best[sel])[0].T
        return colors.reshape(-1, s * s, 3).mean(axis=1)


def _highlight(prim: Primitive, p: np.ndarray, n: np.ndarray, light: np.ndarray,
               eye: np.ndarray) -> np.ndarray:
    """Blinn-Phong highlight (3, N) float32 (white, grey levels) of points (3, N) with normals
    (3, N or 1) seen from ``eye``; the normal is taken on the side facing the camera."""
    v = eye.reshape(3, 1).astype(p.dtype) - p
    v /= np.linalg.norm(v, axis=0, keepdims=True)
    n = np.broadcast_to(n, p.shape)
    n = n * np.sign(np.einsum("in,in->n", n, v) + 1e-12)
    h = v + light.reshape(3, 1).astype(p.dtype)
    h /= np.linalg.norm(h, axis=0, keepdims=True)
    spec = np.clip(np.einsum("in,in->n", n, h), 0.0, 1.0) ** prim.shininess
    return (np.float32(255.0 * prim.specular) * spec.astype(np.float32))[None, :].repeat(3, 0)


class SurfaceTexture(ABC):
    """A texture defined on a primitive's surface coordinates (s, t) in metres
    (:meth:`Primitive.surface_coords`) instead of on 3D points."""

    @abstractmethod
    def sample(self, s: np.ndarray, t: np.ndarray) -> np.ndarray:
        """BGR (3, N) float32 at surface coordinates (s, t) (metres, arrays of N)."""


class PhotoTexture(SurfaceTexture):
    """A photograph on a surface: colour at surface coordinates (s, t) in metres
    (:meth:`Primitive.surface_coords`), the image tiled with ``pixel_size`` metres per pixel,
    bilinear. A grey image is tinted: ``tint_bgr`` (3 factors, 1 = keep grey). ``gain`` and
    ``offset`` adjust its contrast (grey levels)."""

    def __init__(self, image: np.ndarray, pixel_size: float, *,
                 tint_bgr: Sequence[float] = (1.0, 1.0, 1.0), gain: float = 1.0,
                 offset: float = 0.0):
        img = np.asarray(image)
        if img.ndim == 2:
            img = img[..., None].repeat(3, axis=2)
        if img.ndim != 3 or img.shape[2] != 3 or img.shape[0] < 2 or img.shape[1] < 2:
            raise ConfigError(f"a photo texture needs an (H, W) or (H, W, 3) image, got "
                              f"{np.shape(image)}")
        if not pixel_size > 0:
            raise ConfigError(f"photo texture pixel size must be > 0 m, got {pixel_size}")
        tinted = img.astype(np.float32) * np.asarray(tint_bgr, np.float32) * gain + offset
        self.image = np.clip(tinted, 0, 255).astype(np.float32)
        self.pixel_size = float(pixel_size)

    def sample(self, s: np.ndarray, t: np.ndarray) -> np.ndarray:
        """BGR (3, N) float32 at surface coordinates (s, t) (metres, arrays of N)."""
        h, w = self.image.shape[:2]
        u = np.mod(np.asarray(s, np.float64).ravel() / self.pixel_size, w).astype(np.float32)
        v = np.mod(np.asarray(t, np.float64).ravel() / self.pixel_size, h).astype(np.float32)
        n = u.size
        if n == 0:
            return np.zeros((3, 0), np.float32)
        cols = _REMAP_COLS  # cv2.remap maps must stay below 32767 in each dimension
        rows = -(-n // cols)
        mu, mv = np.zeros(rows * cols, np.float32), np.zeros(rows * cols, np.float32)
        mu[:n], mv[:n] = u, v
        out = cv2.remap(self.image, mu.reshape(rows, cols), mv.reshape(rows, cols),
                        cv2.INTER_LINEAR, borderMode=cv2.BORDER_WRAP)
        return out.reshape(-1, 3)[:n].T


_REMAP_COLS = 1024


# A pixel is re-rendered with several rays when its 3x3 neighbourhood spans a silhouette or a
# crease (normals turning by more than ~18 deg) or its surface is seen at a grazing angle
# (compressed texture): there one centre sample would alias.
_CREASE_COS = 0.95
_GRAZING_COS = 0.3


def _aliasing_pixels(idx: np.ndarray, normals: np.ndarray, grid: _RayGrid) -> np.ndarray:
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


def _footprint(prim: Primitive, T_camera_base: np.ndarray, grid: _RayGrid):
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


def _in_footprint(prim: Primitive, T_camera_base: np.ndarray, xn, yn) -> np.ndarray:
    """Boolean mask of the camera rays (xn, yn, 1) that can hit ``prim`` (conservative)."""
    c = prim.corners_base() @ T_camera_base[:3, :3].T + T_camera_base[:3, 3]
    if np.any(c[:, 2] <= 1e-6):
        return np.full(xn.shape, bool(np.any(c[:, 2] > 0)))
    x, y = c[:, 0] / c[:, 2], c[:, 1] / c[:, 2]
    with np.errstate(invalid="ignore"):
        return (xn >= x.min()) & (xn <= x.max()) & (yn >= y.min()) & (yn <= y.max())


def _check_pose(T: np.ndarray) -> np.ndarray:
    return as_rigid(T, "camera pose T_base_camera")


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
    T = _check_pose(T_base_camera)
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
