"""Exact scene geometry for scoring: the primitives a simulated scene is made of.

A :class:`SceneTruth` is what a simulated camera knows about its scene (the mock camera writes
it into the recording as JSON): planar rectangles (the table top, a floor), boxes rotated about
the vertical, upright capped cylinders and spheres, all in the controller's ``base`` frame
(metres). It answers the two questions scoring asks:

- how far is a reconstructed point from the true surface (:meth:`SceneTruth.distance`, exact
  Euclidean distance to the nearest primitive's surface), and
- which objects stand on the table, with centre, size, yaw and height
  (:meth:`SceneTruth.objects`), for scene analysis.

JSON form (stable; more keys may be added)::

    {"primitives": [{"name": "table", "kind": "rectangle", "T_base_local": [[4x4]],
                     "dims": [half_x, half_y]},
                    {"name": "crate", "kind": "box", "T_base_local": ..., "dims": [sx, sy, sz]},
                    {"name": "can", "kind": "cylinder", "T_base_local": ..., "dims": [r, h]},
                    {"name": "ball", "kind": "sphere", "T_base_local": ..., "dims": [r]}],
     "support": "table"}

Local frames: a rectangle spans ``|x| <= half_x, |y| <= half_y`` of its local z = 0 plane; a
box is centred on its local origin; a cylinder's axis is local z from its origin up ``h``; a
sphere is centred on its local origin.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass

import numpy as np

from armstereo.errors import ConfigError
from armstereo.transforms import invert, transform_points

KINDS = {"rectangle": 2, "box": 3, "cylinder": 2, "sphere": 1}  # kind -> number of dims


@dataclass(frozen=True)
class TruthPrimitive:
    """One primitive: ``kind`` (see :data:`KINDS`), its pose ``T_base_local`` and ``dims``
    (metres, meaning per kind in the module doc)."""

    name: str
    kind: str
    T_base_local: np.ndarray
    dims: tuple[float, ...]

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise ConfigError(f"scene primitive {self.name!r}: unknown kind {self.kind!r} "
                              f"(known: {', '.join(KINDS)})")
        if len(self.dims) != KINDS[self.kind] or not all(d > 0 for d in self.dims):
            raise ConfigError(f"scene primitive {self.name!r}: a {self.kind} needs "
                              f"{KINDS[self.kind]} positive dims, got {list(self.dims)}")
        T = np.asarray(self.T_base_local, dtype=float)
        if T.shape != (4, 4) or not np.all(np.isfinite(T)):
            raise ConfigError(f"scene primitive {self.name!r}: T_base_local must be a finite 4x4")
        object.__setattr__(self, "T_base_local", T)

    def distance(self, points_base: np.ndarray) -> np.ndarray:
        """Unsigned Euclidean distance (N,) from points (N, 3, base) to this surface (m)."""
        p = transform_points(invert(self.T_base_local),
                             np.asarray(points_base, float).reshape(-1, 3))
        return np.abs(_SIGNED[self.kind](p, self.dims))

    def top_z(self) -> float:
        """Highest base-frame z of the primitive (m)."""
        corners = transform_points(self.T_base_local, _corners_local(self.kind, self.dims))
        if self.kind == "sphere":
            return float(self.T_base_local[2, 3] + self.dims[0])
        return float(corners[:, 2].max())


@dataclass(frozen=True)
class TruthObject:
    """An object standing on the support plane, described as scene analysis reports objects:
    ``center_m`` (base frame, the solid's centre), ``size_m`` (length >= width along the
    footprint's axes, then height), ``yaw_deg`` of the length axis about base z in
    (-90, 90], ``height_m`` of its top above the support plane."""

    name: str
    kind: str
    center_m: tuple[float, float, float]
    size_m: tuple[float, float, float]
    yaw_deg: float
    height_m: float


class SceneTruth:
    """The exact primitives of a simulated scene; ``support`` names the table top."""

    def __init__(self, primitives: list[TruthPrimitive], support: str | None = None):
        if not primitives:
            raise ConfigError("scene truth needs at least one primitive")
        names = [p.name for p in primitives]
        if support is not None and support not in names:
            raise ConfigError(f"scene truth: support {support!r} is not a primitive")
        self.primitives = tuple(primitives)
        self.support = support

    def distance(self, points_base: np.ndarray) -> np.ndarray:
        """Distance (N,) from each point (N, 3, base) to the nearest true surface (m)."""
        pts = np.asarray(points_base, dtype=float).reshape(-1, 3)
        return np.min([p.distance(pts) for p in self.primitives], axis=0)

    def support_primitive(self) -> TruthPrimitive | None:
        return next((p for p in self.primitives if p.name == self.support), None)

    def support_height(self) -> float:
        """Base-frame z of the support plane (m); 0 when no support is named."""
        sup = self.support_primitive()
        return float(sup.T_base_local[2, 3]) if sup is not None else 0.0

    def objects(self) -> list[TruthObject]:
        """The non-planar primitives as objects on the support plane."""
        z0 = self.support_height()
        return [_as_object(p, z0) for p in self.primitives if p.kind != "rectangle"]

    def to_json(self) -> str:
        return json.dumps({"primitives": [
            {"name": p.name, "kind": p.kind, "T_base_local": p.T_base_local.tolist(),
             "dims": list(p.dims)} for p in self.primitives], "support": self.support})

    @classmethod
    def from_json(cls, text: str) -> SceneTruth:
        """Parse :meth:`to_json` output; ConfigError names what is malformed."""
        try:
            doc = json.loads(text)
            prims = [TruthPrimitive(str(d["name"]), str(d["kind"]),
                                    np.asarray(d["T_base_local"], dtype=float),
                                    tuple(float(v) for v in d["dims"]))
                     for d in doc["primitives"]]
            return cls(prims, doc.get("support"))
        except (ValueError, KeyError, TypeError) as err:
            raise ConfigError(f"scene truth is malformed: {err}") from None


def _as_object(p: TruthPrimitive, z0: float) -> TruthObject:
    R, t = p.T_base_local[:3, :3], p.T_base_local[:3, 3]
    if p.kind == "box":
        sx, sy, sz = p.dims
        yaw = math.atan2(R[1, 0], R[0, 0]) + (0.0 if sx >= sy else math.pi / 2)
        size = (max(sx, sy), min(sx, sy), sz)
        center = t
    elif p.kind == "cylinder":
        r, h = p.dims
        yaw, size, center = 0.0, (2 * r, 2 * r, h), t + R[:, 2] * h / 2
    else:
        r = p.dims[0]
        yaw, size, center = 0.0, (2 * r, 2 * r, 2 * r), t
    return TruthObject(p.name, p.kind, tuple(float(v) for v in center),
                       tuple(float(v) for v in size), _wrap_yaw_deg(yaw), p.top_z() - z0)


def _wrap_yaw_deg(yaw: float) -> float:
    """Yaw of an axis (a line, not a direction) in (-90, 90] degrees."""
    d = math.degrees(yaw) % 180.0
    return d - 180.0 if d > 90.0 else d


def _rectangle_sdf(p: np.ndarray, dims) -> np.ndarray:
    hx, hy = dims
    dx = np.maximum(np.abs(p[:, 0]) - hx, 0.0)
    dy = np.maximum(np.abs(p[:, 1]) - hy, 0.0)
    return np.sqrt(dx * dx + dy * dy + p[:, 2] ** 2)


def _box_sdf(p: np.ndarray, dims) -> np.ndarray:
    q = np.abs(p) - np.asarray(dims) / 2
    outside = np.linalg.norm(np.maximum(q, 0.0), axis=1)
    return outside + np.minimum(q.max(axis=1), 0.0)


def _cylinder_sdf(p: np.ndarray, dims) -> np.ndarray:
    r, h = dims
    q = np.stack([np.hypot(p[:, 0], p[:, 1]) - r, np.abs(p[:, 2] - h / 2) - h / 2], axis=1)
    outside = np.linalg.norm(np.maximum(q, 0.0), axis=1)
    return outside + np.minimum(q.max(axis=1), 0.0)


def _sphere_sdf(p: np.ndarray, dims) -> np.ndarray:
    return np.linalg.norm(p, axis=1) - dims[0]


_SIGNED = {"rectangle": _rectangle_sdf, "box": _box_sdf, "cylinder": _cylinder_sdf,
           "sphere": _sphere_sdf}


def _corners_local(kind: str, dims) -> np.ndarray:
    signs = np.array([[i, j, k] for i in (-1, 1) for j in (-1, 1) for k in (-1, 1)], float)
    if kind == "rectangle":
        return signs * (dims[0], dims[1], 0.0)
    if kind == "box":
        return signs * np.asarray(dims) / 2
    if kind == "cylinder":
        return signs * (dims[0], dims[0], dims[1] / 2) + (0.0, 0.0, dims[1] / 2)
    return signs * dims[0]
