"""A picture of a fused mesh, drawn headless (no display, no OpenGL).

The mesh is seen by a virtual pinhole camera (OpenCV frame, pixel centres at integer
coordinates) that looks at its centre from an oblique angle above it and is zoomed so that the
mesh fills the picture. Triangles are rasterised with a depth buffer (a small numba kernel:
edge functions at pixel centres, depth interpolated in 1/z), at ``SUPERSAMPLE`` times the size
and then shrunk, which smooths the edges. Two styles: ``color`` (the vertex colours the views
gave, lit) and ``shape`` (a grey surface lit from the camera's upper left: the geometry alone,
where colour would hide a bump or a hole).
"""

from __future__ import annotations

import math

import cv2
import numpy as np
from numba import njit

from armstereo.errors import ConfigError
from armstereo.fusion.mesh import Mesh

SUPERSAMPLE = 2
AMBIENT = 0.35
BACKGROUND_BGR = (255, 255, 255)
SHAPE_BGR = np.array([200.0, 200.0, 200.0])
# Direction towards the light in the camera frame: upper left, behind the viewer.
LIGHT_CAMERA = np.array([-0.4, -0.6, -1.0])
STYLES = ("color", "shape")
FILL = 0.92  # share of the image the framed mesh spans
FRAME_PERCENTILE = 0.2  # per side, vertices left out of the framing


def view_pose(center: np.ndarray, distance: float, azimuth_deg: float,
              elevation_deg: float) -> np.ndarray:
    """T_base_camera of a camera ``distance`` m from ``center`` (base frame) at azimuth (about
    base z, from +x) and elevation (deg), looking at it with image up = world up."""
    from armstereo.capture.scan_plan import look_at_pose

    return look_at_pose(np.asarray(center, float), math.radians(azimuth_deg),
                        math.radians(elevation_deg), distance)


def framing_camera(mesh: Mesh, size: tuple[int, int], *, azimuth_deg: float = 215.0,
                   elevation_deg: float = 40.0, fov_deg: float = 40.0
                   ) -> tuple[np.ndarray, np.ndarray]:
    """(T_base_camera, K) of a camera at (azimuth, elevation) deg from the mesh's centre, at the
    distance where its bounding sphere fits ``fov_deg``, then zoomed and centred so the mesh
    (all but FRAME_PERCENTILE % of the vertices each side: stray bits do not shrink it) fills
    the image of ``size`` (w, h) up to FILL."""
    if len(mesh) == 0:
        raise ConfigError("cannot frame an empty mesh")
    v = mesh.vertices.astype(np.float64)
    lo, hi = np.percentile(v, [FRAME_PERCENTILE, 100 - FRAME_PERCENTILE], axis=0)
    center, radius = (lo + hi) / 2, max(float(np.linalg.norm(hi - lo)) / 2, 1e-3)
    distance = radius / math.sin(math.radians(fov_deg) / 2)
    T = view_pose(center, distance, azimuth_deg, elevation_deg)
    cam = (v - T[:3, 3]) @ T[:3, :3]
    cam = cam[cam[:, 2] > 1e-6]
    xy = cam[:, :2] / cam[:, 2:3]  # normalised image coordinates
    (x_lo, y_lo), (x_hi, y_hi) = np.percentile(xy, [FRAME_PERCENTILE,
                                                    100 - FRAME_PERCENTILE], axis=0)
    w, h = size
    f = FILL * min(w / max(x_hi - x_lo, 1e-9), h / max(y_hi - y_lo, 1e-9))
    cx = (w - 1) / 2 - f * (x_lo + x_hi) / 2
    cy = (h - 1) / 2 - f * (y_lo + y_hi) / 2
    return T, np.array([[f, 0.0, cx], [0.0, f, cy], [0.0, 0.0, 1.0]])


def render_mesh(mesh: Mesh, T_base_camera: np.ndarray, K: np.ndarray, size: tuple[int, int],
                style: str = "color") -> np.ndarray:
    """BGR uint8 image (h, w, 3) of ``mesh`` (base frame, m) seen by the pinhole ``K`` at
    ``T_base_camera`` (OpenCV frame, base), ``size`` = (w, h); see the module docstring."""
    if style not in STYLES:
        raise ConfigError(f"render style must be one of {', '.join(STYLES)}, got {style!r}")
    w, h = size
    s = SUPERSAMPLE
    image = np.full((h * s, w * s, 3), BACKGROUND_BGR, np.uint8)
    if len(mesh):
        R, t = T_base_camera[:3, :3], T_base_camera[:3, 3]
        cam = (mesh.vertices.astype(np.float64) - t) @ R  # vertices in the camera frame
        tri = cam[mesh.faces]  # (M, 3, 3)
        keep = np.all(tri[:, :, 2] > 1e-6, axis=1)
        tri, faces = tri[keep], mesh.faces[keep]
        uv = tri[:, :, :2] / tri[:, :, 2:3] * np.diag(K)[:2] + K[:2, 2]
        uv = (uv + 0.5) * s - 0.5  # pixel centres stay at integers in the larger image
        colors = _face_colors(mesh, tri, faces, style)
        zbuf = np.full((h * s, w * s), np.inf)
        _rasterize(uv, 1.0 / tri[:, :, 2], colors, image, zbuf)
    return cv2.resize(image, (w, h), interpolation=cv2.INTER_AREA)


@njit(cache=True, nogil=True)
def _rasterize(uv, inv_z, colors, image, zbuf):  # pragma: no cover - compiled
    """Fill every triangle (uv (M, 3, 2) px, inv_z (M, 3) 1/m, colours (M, 3) uint8) into
    ``image`` where it is nearer than ``zbuf`` (depth; both updated in place)."""
    h, w = zbuf.shape
    for i in range(uv.shape[0]):
        x0, y0 = uv[i, 0, 0], uv[i, 0, 1]
        x1, y1 = uv[i, 1, 0], uv[i, 1, 1]
        x2, y2 = uv[i, 2, 0], uv[i, 2, 1]
        area = (x1 - x0) * (y2 - y0) - (x2 - x0) * (y1 - y0)
        if abs(area) < 1e-12:
            continue
        u_lo = max(int(math.ceil(min(x0, x1, x2))), 0)
        u_hi = min(int(math.floor(max(x0, x1, x2))), w - 1)
        v_lo = max(int(math.ceil(min(y0, y1, y2))), 0)
        v_hi = min(int(math.floor(max(y0, y1, y2))), h - 1)
        for v in range(v_lo, v_hi + 1):
            for u in range(u_lo, u_hi + 1):
                a = ((x1 - u) * (y2 - v) - (x2 - u) * (y1 - v)) / area
                b = ((x2 - u) * (y0 - v) - (x0 - u) * (y2 - v)) / area
                c = 1.0 - a - b
                if a < 0.0 or b < 0.0 or c < 0.0:
                    continue
                z = 1.0 / (a * inv_z[i, 0] + b * inv_z[i, 1] + c * inv_z[i, 2])
                if z < zbuf[v, u]:
                    zbuf[v, u] = z
                    image[v, u, 0] = colors[i, 0]
                    image[v, u, 1] = colors[i, 1]
                    image[v, u, 2] = colors[i, 2]


def _face_colors(mesh: Mesh, tri: np.ndarray, faces: np.ndarray, style: str) -> np.ndarray:
    """Per face BGR (M, 3) uint8: base colour times (ambient + diffuse), two-sided."""
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)
    light = LIGHT_CAMERA / np.linalg.norm(LIGHT_CAMERA)
    diffuse = np.abs(n @ light)  # two-sided: a face seen from behind is lit like its front
    base = (SHAPE_BGR[None, :] if style == "shape"
            else mesh.colors[faces].astype(np.float64).mean(axis=1))
    shade = AMBIENT + (1.0 - AMBIENT) * diffuse
    return np.clip(base * shade[:, None], 0, 255).astype(np.uint8)


def mesh_picture(mesh: Mesh, size: tuple[int, int] = (640, 480), **view) -> np.ndarray:
    """The two styles side by side (colour left, shape right), each ``size``, from the
    framing camera (:func:`framing_camera`, ``view`` passes its angles)."""
    T, K = framing_camera(mesh, size, **view)
    return np.hstack([render_mesh(mesh, T, K, size, "color"),
                      render_mesh(mesh, T, K, size, "shape")])
