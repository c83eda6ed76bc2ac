"""The mock scenes' shapes: finite rectangles, boxes rotated about z, upright capped cylinders
and spheres, in the controller's ``base`` frame (metres).

Each :class:`Primitive` has a local frame ``T_base_local`` and a texture
(:mod:`drivers.mock.texture`), intersects rays analytically (vectorised numpy, float32 rays
stay float32), gives its outward normals, a convex bound for culling and its exact geometry for
scoring (:class:`armstereo.evaluation.scene_truth.TruthPrimitive`).
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Sequence

import numpy as np

from armstereo.errors import ConfigError
from armstereo.evaluation.scene_truth import TruthPrimitive
from armstereo.transforms import invert, make_T, rot_z
from drivers.mock.texture import SurfaceTexture, Texture

T_MIN = 1e-9  # rays start this far from their origin (m), so a surface never hits itself


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



class BowedRectangle(Rectangle):
    """A rectangle ``|x| <= half_x, |y| <= half_y`` bent into the shallow paraboloid
    ``z = curv_x x^2 + curv_y y^2 + z0`` (local frame, m), ``z0`` chosen so that the corners lie
    in z = 0: a printed sheet that does not lie flat. Its normal is local +z tilted by the
    slope; it is visible from both sides. Surface coordinates are (x, y), which differ from arc
    lengths by far less than a micrometre for bows of a millimetre over decimetres."""

    def __init__(self, T_base_local: np.ndarray, half_x: float, half_y: float,
                 texture, *, curv_x: float, curv_y: float, name: str = "bowed rectangle"):
        super().__init__(T_base_local, half_x, half_y, texture, name)
        self.curv_x, self.curv_y = float(curv_x), float(curv_y)
        self.z0 = -(self.curv_x * self.half_x ** 2 + self.curv_y * self.half_y ** 2)

    def _hit_local(self, o, dx, dy, dz):
        kx, ky = o.dtype.type(self.curv_x), o.dtype.type(self.curv_y)
        a = kx * dx * dx + ky * dy * dy
        b = 2.0 * (kx * o[0] * dx + ky * o[1] * dy) - dz
        c = kx * o[0] ** 2 + ky * o[1] ** 2 + o.dtype.type(self.z0) - o[2]
        disc = b * b - 4.0 * a * c
        q = -0.5 * (b + np.copysign(np.sqrt(np.maximum(disc, 0.0)), b))
        t1, t2 = q / a, c / q  # the stable pair of roots; t2 is the plane's when a = 0
        t = np.inf
        for root in (t1, t2):
            x, y = o[0] + root * dx, o[1] + root * dy
            t = np.minimum(t, _miss_where(root, ~(disc >= 0) | (np.abs(x) > self.half_x)
                                         | (np.abs(y) > self.half_y)))
        return t

    def _normal_local(self, p):
        n = np.stack([-2.0 * self.curv_x * p[0], -2.0 * self.curv_y * p[1], np.ones_like(p[0])])
        return n / np.linalg.norm(n, axis=0, keepdims=True)

    def normals(self, points_base: np.ndarray) -> np.ndarray:
        return Primitive.normals(self, points_base)

    def _corners_local(self):
        hx, hy = self.half_x, self.half_y
        return np.array([[sx * hx, sy * hy, z] for sx in (-1, 1) for sy in (-1, 1)
                         for z in (0.0, self.z0)], dtype=float)
