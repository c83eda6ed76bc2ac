"""Read the cloud to analyse: a PLY file or an MCAP with a ``/points`` point cloud.

Whatever the source, the result is a :class:`SceneCloud` in the robot's ``base`` frame, metres.
Inputs are checked on entry, because a wrong cloud gives a plausible-looking but wrong scene:

- PLY comments and MCAP ``frame_id`` name the frame; a cloud in another frame is refused
  (ConfigError), a PLY that names none is taken as ``base`` with a warning;
- non-finite points are dropped; an empty cloud or one with fewer than
  :data:`MIN_CLOUD_POINTS` points is refused;
- a cloud whose bulk spans more than :data:`MAX_EXTENT_M` is refused as probably not metres.
"""

from __future__ import annotations

import logging
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from armstereo.errors import ConfigError, RecordingError, StereoError
from armstereo.io.ply import read_ply
from armstereo.recording import Recording
from armstereo.recording.schemas import FRAME_BASE, TOPIC_POINTS

log = logging.getLogger(__name__)

MIN_CLOUD_POINTS = 100  # fewer points cannot hold a plane and objects on it
MAX_EXTENT_M = 20.0  # a tabletop cloud wider than this (1st..99th percentile) is not in metres
EXTENT_PERCENTILES = (1.0, 99.0)
_FRAME_COMMENT = re.compile(r"\bframe\s+([A-Za-z0-9_/\-]+)")


@dataclass(frozen=True)
class SceneCloud:
    """A cloud to analyse: ``points`` (N, 3) float64 metres in ``frame_id`` (always ``base``
    after :func:`load_cloud`), ``colors_bgr`` (N, 3) uint8 or None, where it came from, and
    the source's metadata (MCAP ``armstereo`` record, empty for PLY)."""

    points: np.ndarray
    colors_bgr: np.ndarray | None
    frame_id: str
    source: str
    metadata: dict[str, str] = field(default_factory=dict)
    timestamp_ns: int = 0  # when the cloud was taken (MCAP log time), 0 if unknown


def load_cloud(path: str | Path) -> SceneCloud:
    """Read ``path`` (``.ply``, or ``.mcap`` holding ``/points``) and check it (module doc).

    Raises ConfigError for a missing, malformed, empty, tiny, non-metric or foreign-frame
    cloud, RecordingError for an MCAP without a readable ``/points`` message.
    """
    path = Path(path)
    if not path.is_file():
        raise ConfigError(f"no such file: {path}")
    suffix = path.suffix.lower()
    if suffix == ".ply":
        cloud = _read_ply_cloud(path)
    elif suffix == ".mcap":
        cloud = _read_mcap_cloud(path)
    else:
        raise ConfigError(f"{path}: expected a .ply cloud or a .mcap with {TOPIC_POINTS}, "
                          f"not {suffix or 'a file without extension'}")
    return check_cloud(cloud)


def check_cloud(cloud: SceneCloud) -> SceneCloud:
    """Refuse clouds in another frame, empty, tiny or non-metric clouds; drop non-finite
    points. Returns the cleaned cloud (points as float64)."""
    if cloud.frame_id != FRAME_BASE:
        raise ConfigError(f"{cloud.source}: the cloud is in frame '{cloud.frame_id}'; scene "
                          f"analysis needs it in the robot's '{FRAME_BASE}' frame (transform it "
                          "first: heights and 'up' are measured in that frame)")
    pts = np.asarray(cloud.points, dtype=float)
    if pts.ndim != 2 or pts.shape[1] != 3:
        raise ConfigError(f"{cloud.source}: points must be (N, 3), got shape {pts.shape}")
    colors = cloud.colors_bgr
    if colors is not None and (colors.shape != pts.shape or colors.dtype != np.uint8):
        raise ConfigError(f"{cloud.source}: colours must be uint8 {pts.shape}, got "
                          f"{colors.dtype} {colors.shape}")
    finite = np.all(np.isfinite(pts), axis=1)
    if not finite.all():
        log.info("%s: dropped %d non-finite point(s)", cloud.source, int((~finite).sum()))
        pts = pts[finite]
        colors = None if colors is None else colors[finite]
    if len(pts) == 0:
        raise ConfigError(f"{cloud.source}: the cloud is empty (no finite point)")
    if len(pts) < MIN_CLOUD_POINTS:
        raise ConfigError(f"{cloud.source}: the cloud has only {len(pts)} point(s); scene "
                          f"analysis needs at least {MIN_CLOUD_POINTS}")
    lo, hi = np.percentile(pts, EXTENT_PERCENTILES, axis=0)
    extent = float(np.max(hi - lo))
    if extent > MAX_EXTENT_M:
        raise ConfigError(f"{cloud.source}: the bulk of the cloud spans {extent:.1f} units; "
                          f"more than {MAX_EXTENT_M:.0f} m for a tabletop, so it is probably "
                          "not in metres")
    return SceneCloud(pts, colors, cloud.frame_id, cloud.source, dict(cloud.metadata),
                      int(cloud.timestamp_ns))


def _read_ply_cloud(path: Path) -> SceneCloud:
    try:
        ply = read_ply(path)
    except StereoError as err:  # read_ply's own message names the file and the problem
        raise ConfigError(str(err)) from None
    frames = [m.group(1) for c in ply.comments if (m := _FRAME_COMMENT.search(c))]
    if frames:
        frame = frames[0]
    else:
        log.warning("%s names no frame in its comments; taking it as '%s'", path.name,
                    FRAME_BASE)
        frame = FRAME_BASE
    return SceneCloud(ply.points, ply.colors_bgr, frame, str(path))


def _read_mcap_cloud(path: Path) -> SceneCloud:
    rec = Recording.open(path)
    clouds = [c for c in rec.point_clouds if c.topic == TOPIC_POINTS]
    if not clouds:
        lost = f" ({'; '.join(rec.lost)})" if rec.lost else ""
        raise RecordingError(f"{path} has no readable {TOPIC_POINTS} point cloud{lost}; a "
                             "capture recording must be reconstructed first (armstereo "
                             "reconstruct)")
    if len(clouds) > 1:
        log.warning("%s holds %d clouds on %s; analysing the last one", path.name, len(clouds),
                    TOPIC_POINTS)
    c = max(clouds, key=lambda cl: cl.timestamp_ns)
    frame = c.frame_id
    if not frame:
        log.warning("%s: the %s cloud has no frame_id; taking it as '%s'", path.name,
                    TOPIC_POINTS, FRAME_BASE)
        frame = FRAME_BASE
    return SceneCloud(c.points, c.colors_bgr, frame, str(path), dict(rec.metadata),
                      int(c.timestamp_ns))
