"""Writing imported views and pairs as an armstereo recording (the format capture writes)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from armstereo.camera_model import Intrinsics
from armstereo.errors import ConfigError
from armstereo.frame import Frame
from armstereo.kinematics import JOINT_NAMES
from armstereo.recording import RecordingWriter

# (pair, left view, right view, commanded baseline m, achieved m, direction, viewpoint)
PairRow = tuple[int, int, int, float, float, str, int | None]


@dataclass(frozen=True, eq=False)
class ViewRecord:
    """One imported view: image (uint8 BGR/grey) at its stamp (ns), intrinsics, poses in
    ``base`` (m), the arm's joints (rad, UR order) if known, and what else capture records."""

    index: int
    stamp_ns: int
    image: np.ndarray
    intrinsics: Intrinsics
    T_base_flange: np.ndarray
    T_flange_camera: np.ndarray
    joints: np.ndarray | None
    settle_s: float
    controller_T_base_flange: np.ndarray | None = None
    depth: np.ndarray | None = None
    sees_board: bool = False


def check_output(path: Path, force: bool, flag: str = "--out") -> None:
    """ConfigError unless ``path`` may be written (absent, or ``force``)."""
    if not str(path).strip():
        raise ConfigError(f"{flag} is empty")
    if path.is_dir():
        raise ConfigError(f"{flag} {path} is a directory; give a file name")
    if path.exists() and not force:
        raise ConfigError(f"{flag} {path} exists; pass --force to overwrite it")
    if not path.parent.exists():
        raise ConfigError(f"{flag} directory {path.parent} does not exist")


def write_recording(path: Path, views: Sequence[ViewRecord], pairs: Sequence[PairRow],
                    metadata: dict[str, str], *, calibration_ns: int | None = None) -> None:
    """Write ``views`` (in time order) and ``pairs`` to ``path``; a camera calibration before
    the first view (at ``calibration_ns`` if given) and again wherever it changes."""
    views = sorted(views, key=lambda v: v.stamp_ns)
    with RecordingWriter(path, metadata=metadata) as w:
        current = None
        for k, v in enumerate(views):
            if current is None or not _same(current, v.intrinsics):
                t = (calibration_ns if k == 0 and calibration_ns is not None
                     else v.stamp_ns - 1)
                w.write_calibration(v.intrinsics, t)
                current = v.intrinsics
            q = np.zeros(0) if v.joints is None else np.asarray(v.joints, dtype=float)
            w.write_view(v.index, Frame(v.image, v.stamp_ns, v.depth), q,
                         JOINT_NAMES if len(q) else (), v.T_base_flange, v.T_flange_camera,
                         settle_s=v.settle_s,
                         controller_T_base_flange=v.controller_T_base_flange)
        for pair, left, right, commanded, achieved, direction, viewpoint in pairs:
            w.write_pair(pair, left, right, commanded, achieved, direction,
                         viewpoint=viewpoint)


def _same(a: Intrinsics, b: Intrinsics) -> bool:
    return a.size == b.size and np.array_equal(a.K, b.K) and np.array_equal(a.dist, b.dist)
