"""The mock renderer: a :class:`Scene` of primitives in the controller's ``base`` frame, lit by
a directional light, ray-cast into an image and its exact depth.

Lighting is Lambertian under a light fixed in the base frame, so it does not depend on the
viewpoint, except on glossy primitives (``specular > 0``, Blinn-Phong): their highlights move
with the camera, as on real varnish, ceramics and plastic.

:meth:`Scene.render` casts a ray through every pixel centre (numpy, vectorised) through the
camera's lens model, including OpenCV distortion (:mod:`drivers.mock.rays`), plus several rays
per pixel where one would alias (silhouettes, creases, grazing surfaces, a printed board's
edges), and returns a BGR image and the exact z-depth at each pixel centre.
"""

from __future__ import annotations

from collections.abc import Sequence

import cv2
import numpy as np

from armstereo.camera_model import Intrinsics
from armstereo.errors import ConfigError
from armstereo.evaluation.scene_truth import SceneTruth
from armstereo.transforms import as_rigid, invert, make_T
from drivers.mock.primitives import Primitive
from drivers.mock.rays import RayGrid, aliasing_pixels, footprint, in_footprint, ray_grid

MAX_SUPERSAMPLE = 4
DEFAULT_LIGHT = (0.3, 0.2, 1.0)  # direction towards the light, base frame
DEFAULT_AMBIENT = 0.45
EDGE_STEP = 8.0  # grey levels between neighbouring pixels that mark a hard texture edge


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
        T = as_rigid(T_base_camera, "camera pose T_base_camera")
        s = int(supersample)
        if not 1 <= s <= MAX_SUPERSAMPLE or s != supersample:
            raise ConfigError(f"supersample must be an integer in 1..{MAX_SUPERSAMPLE}, "
                              f"got {supersample}")
        grid = ray_grid(intrinsics)
        t, idx, blocks = self._cast(T, grid)
        img, normals = self._shade_grid(T, grid, t, idx, blocks)
        edges = self._sharp_edge_pixels(img, idx)
        if s > 1:
            rows, cols = np.nonzero(aliasing_pixels(idx, normals, grid) & ~edges)
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

    def _cast(self, T_base_camera: np.ndarray, grid: RayGrid):
        """z-buffer over the ray grid: ray parameter (= z-depth), primitive index, and the grid
        block each primitive can cover."""
        shape = grid.xn.shape
        t_best = np.full(shape, np.inf, dtype=np.float32)
        idx = np.full(shape, -1, dtype=np.int16)
        T_camera_base = invert(T_base_camera)
        blocks = []
        for i, prim in enumerate(self.primitives):
            block = footprint(prim, T_camera_base, grid)
            blocks.append(block)
            if block is None:
                continue
            t = prim.hit(T_base_camera, grid.xn[block], grid.yn[block], np.float32(1.0))
            tb, ib = t_best[block], idx[block]
            better = t < tb
            tb[better] = t[better]
            ib[better] = i
        return t_best, idx, blocks

    def _shade_grid(self, T: np.ndarray, grid: RayGrid, t: np.ndarray, idx: np.ndarray,
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
            cand = np.flatnonzero(in_footprint(prim, T_camera_base, xn, yn))
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
