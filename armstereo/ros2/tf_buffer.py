"""A TF tree read from a bag, with tf2's semantics, looked up for many stamps at once.

Each frame has one parent. A ``/tf`` edge is a time series of ``T_parent_child`` (header stamp,
integer ns): between two samples the translation is interpolated linearly and the rotation by
slerp, as tf2 does; outside its first and last sample it is unknown (tf2's extrapolation
error). A ``/tf_static`` edge holds at every time. A lookup ``T_target_source`` walks both
frames up to their common root; frames in different trees have no transform.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from armstereo.errors import RecordingError
from armstereo.transforms import matrix_from_quaternion_xyzw


@dataclass
class _Edge:
    parent: str
    stamps: list[int]
    xyz: list[tuple[float, float, float]]
    quat: list[tuple[float, float, float, float]]


class TfBuffer:
    """Collects transforms with :meth:`add`, then :meth:`finish` checks and indexes them."""

    def __init__(self) -> None:
        self._dynamic: dict[str, _Edge] = {}
        self._static: dict[str, tuple[str, np.ndarray]] = {}
        self.rejected = 0  # transforms that were not finite poses
        self._conflict: tuple[str, str, str] | None = None  # a frame given a second parent
        self._arrays: dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]] = {}

    # ------------------------------------------------------------------------- building
    def add(self, tf_message, *, static: bool, stamp_of) -> None:
        """Add every transform of a TFMessage; ``stamp_of(header) -> ns``."""
        for tr in tf_message.transforms:
            parent = tr.header.frame_id.lstrip("/")
            child = tr.child_frame_id.lstrip("/")
            t, q = tr.transform.translation, tr.transform.rotation
            xyz, quat = (t.x, t.y, t.z), (q.x, q.y, q.z, q.w)
            norm = float(np.linalg.norm(quat))
            if not parent or not child or parent == child or not np.all(np.isfinite(xyz)) \
                    or not np.isfinite(norm) or norm < 1e-9:
                self.rejected += 1
                continue
            quat = tuple(v / norm for v in quat)
            if static:
                self._static[child] = (parent, _matrix(xyz, quat))
                continue
            edge = self._dynamic.setdefault(child, _Edge(parent, [], [], []))
            if edge.parent != parent:
                self._conflict = self._conflict or (child, edge.parent, parent)
                continue
            edge.stamps.append(int(stamp_of(tr.header)))
            edge.xyz.append(xyz)
            edge.quat.append(quat)

    def finish(self) -> None:
        """Index the samples; RecordingError when an edge's stamps go back in time or a frame
        has two parents."""
        if self._conflict:
            child, a, b = self._conflict
            raise RecordingError(f"/tf: frame {child} has two parents, {a} and {b} (a TF tree "
                                 "gives each frame one)")
        for child, edge in self._dynamic.items():
            stamps = np.asarray(edge.stamps, dtype=np.int64)
            back = np.flatnonzero(np.diff(stamps) < 0)
            if back.size:
                k = int(back[0])
                raise RecordingError(
                    f"/tf: the stamps of {edge.parent} -> {child} go back in time at sample "
                    f"{k + 1} ({stamps[k + 1]} ns after {stamps[k]} ns); the bag's time stamps "
                    "are out of order")
            keep = np.ones(len(stamps), bool)
            keep[1:] = np.diff(stamps) > 0  # repeated stamps: the first sample counts
            self._arrays[child] = (stamps[keep], np.asarray(edge.xyz, dtype=float)[keep],
                                   np.asarray(edge.quat, dtype=float)[keep])
        for child in self._static:
            if child in self._dynamic:
                raise RecordingError(f"frame {child} is on both /tf and /tf_static")

    # ------------------------------------------------------------------------- queries
    @property
    def frames(self) -> set[str]:
        out = set(self._static) | set(self._dynamic)
        out |= {p for p, _ in self._static.values()} | {e.parent for e in self._dynamic.values()}
        return out

    def parent(self, frame: str) -> str | None:
        if frame in self._static:
            return self._static[frame][0]
        edge = self._dynamic.get(frame)
        return None if edge is None else edge.parent

    def path_to_root(self, frame: str) -> list[str]:
        """``frame``, its parent, ... up to its tree's root (RecordingError on a loop)."""
        path = [frame]
        while (p := self.parent(path[-1])) is not None:
            if p in path:
                raise RecordingError(f"TF has a loop through {p}")
            path.append(p)
        return path

    def chain_problem(self, target: str, source: str) -> str | None:
        """Why there is no transform from ``source`` to ``target`` (None if there is one)."""
        missing = [f for f in (target, source) if f not in self.frames]
        if missing:
            return (f"no frame {' or '.join(missing)} in the bag's TF (frames: "
                    f"{', '.join(sorted(self.frames)) or 'none'})")
        a, b = self.path_to_root(target), self.path_to_root(source)
        if a[-1] != b[-1]:
            return (f"no TF chain from {target} to {source}: {target}'s tree ends at {a[-1]}, "
                    f"{source}'s at {b[-1]}")
        return None

    def coverage(self, target: str, source: str) -> tuple[int, int] | None:
        """The stamps (ns) where every dynamic edge of the chain is known, None if none."""
        lo, hi = -(2**63), 2**63 - 1
        for child in self._chain_edges(target, source):
            if child in self._arrays:
                stamps = self._arrays[child][0]
                lo, hi = max(lo, int(stamps[0])), min(hi, int(stamps[-1]))
        return (lo, hi) if lo <= hi else None

    def _chain_edges(self, target: str, source: str) -> list[str]:
        a, b = self.path_to_root(target), self.path_to_root(source)
        common = next(f for f in a if f in b)
        return a[:a.index(common)] + b[:b.index(common)]

    def lookup(self, target: str, source: str, times: np.ndarray) -> tuple[np.ndarray,
                                                                           np.ndarray]:
        """(T_target_source (N, 4, 4), valid (N,)) at integer-ns ``times``; invalid where a
        dynamic edge would have to be extrapolated. RecordingError without a chain."""
        problem = self.chain_problem(target, source)
        if problem:
            raise RecordingError(problem)
        times = np.asarray(times, dtype=np.int64).reshape(-1)
        a, b = self.path_to_root(target), self.path_to_root(source)
        common = next(f for f in a if f in b)
        valid = np.ones(len(times), bool)
        T_common_target = self._compose(a[:a.index(common)], times, valid)
        T_common_source = self._compose(b[:b.index(common)], times, valid)
        return _invert_many(T_common_target) @ T_common_source, valid

    def _compose(self, frames: list[str], times: np.ndarray, valid: np.ndarray) -> np.ndarray:
        """T_top_frames[0] for a path frames[0] -> ... -> top (the parent of frames[-1])."""
        T = np.broadcast_to(np.eye(4), (len(times), 4, 4)).copy()
        for child in frames:  # from the bottom up: T = T_parent_child @ T
            T = self._edge(child, times, valid) @ T
        return T

    def _edge(self, child: str, times: np.ndarray, valid: np.ndarray) -> np.ndarray:
        if child in self._static:
            return np.broadcast_to(self._static[child][1], (len(times), 4, 4))
        stamps, xyz, quat = self._arrays[child]
        valid &= (times >= stamps[0]) & (times <= stamps[-1])
        hi = np.clip(np.searchsorted(stamps, times, side="left"), 0, len(stamps) - 1)
        lo = np.clip(hi - 1, 0, len(stamps) - 1)
        exact = stamps[hi] == times
        lo = np.where(exact, hi, lo)
        span = (stamps[hi] - stamps[lo]).astype(float)
        w = np.where(span > 0, (times - stamps[lo]) / np.where(span > 0, span, 1.0), 0.0)
        w = np.clip(w, 0.0, 1.0)
        p = xyz[lo] + (xyz[hi] - xyz[lo]) * w[:, None]
        q = _slerp(quat[lo], quat[hi], w)
        T = np.zeros((len(times), 4, 4))
        T[:, :3, :3] = _matrices(q)
        T[:, :3, 3] = p
        T[:, 3, 3] = 1.0
        return T


def _matrix(xyz, quat) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = matrix_from_quaternion_xyzw(np.asarray(quat, dtype=float))
    T[:3, 3] = xyz
    return T


def _slerp(q0: np.ndarray, q1: np.ndarray, w: np.ndarray) -> np.ndarray:
    """Spherical interpolation of unit quaternions (rows), the short way round."""
    dot = np.clip(np.sum(q0 * q1, axis=1), -1.0, 1.0)
    theta = np.arccos(np.abs(dot))
    small = theta < 1e-9
    s = np.where(small, 1.0, np.sin(theta))
    a = np.where(small, 1.0 - w, np.sin((1.0 - w) * theta) / s)
    b = np.where(small, w, np.sin(w * theta) / s) * np.where(dot < 0, -1.0, 1.0)
    q = a[:, None] * q0 + b[:, None] * q1
    return q / np.linalg.norm(q, axis=1, keepdims=True)


def _matrices(q: np.ndarray) -> np.ndarray:
    x, y, z, w = q.T
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)], axis=1),
        np.stack([2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)], axis=1),
        np.stack([2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)], axis=1),
    ], axis=1)


def _invert_many(T: np.ndarray) -> np.ndarray:
    R = np.transpose(T[:, :3, :3], (0, 2, 1))
    out = np.zeros_like(T)
    out[:, :3, :3] = R
    out[:, :3, 3] = -np.einsum("nij,nj->ni", R, T[:, :3, 3])
    out[:, 3, 3] = 1.0
    return out
