"""One recorded pair -> a metric, coloured point cloud in the robot's base frame.

Stages (each timed in ``Reconstruction.timings_s``): ``decode`` (the two images), ``rectify``
(Fusiello from the recorded poses, distortion removed in the same remap), ``match`` (the stereo
matcher on the rectified pair), ``triangulate`` (disparity -> depth -> base-frame points), and,
in :func:`write_outputs`, ``write`` (the PLY) plus ``write_extras`` (PNGs and the output MCAP).

Disparity window: the right image is shifted so that the far end of the depth range has
disparity 0, so the matcher searches ``[0, max_disparity]``. With ``max_disparity="auto"`` the
range comes from ``near``/``far`` (given, or guessed from the scene: the arm stands on its
working surface, the plane ``z = 0`` of ``base``), capped at MAX_AUTO_DISPARITY labels.
"""

from __future__ import annotations

import logging
import math
import time
from dataclasses import dataclass, field, replace
from functools import cached_property
from pathlib import Path

import numpy as np

from armstereo.camera_model import Intrinsics
from armstereo.errors import ConfigError, RecordingError
from armstereo.frame import Frame
from armstereo.io.images import (
    colorize_disparity,
    depth_error_map,
    side_by_side,
    write_depth_png,
    write_png,
)
from armstereo.io.ply import write_ply
from armstereo.reconstruct.rectify import (
    RectifiedPair,
    StereoGeometry,
    rectified_geometry,
    rectify_pair,
)
from armstereo.reconstruct.stereo import METHODS, compute_disparity
from armstereo.reconstruct.triangulate import (
    depth_from_disparity,
    depth_in_original_view,
    point_cloud,
)
from armstereo.recording import Pair, RecordingWriter

log = logging.getLogger(__name__)

DEFAULT_NEAR_M = 0.3  # working range when the scene gives no hint
DEFAULT_FAR_M = 1.5
TABLE_FAR_MARGIN = 1.1  # far = this x the deepest table point seen
TABLE_NEAR_SHARE = 0.5  # near = this x the nearest table point (objects up to half the height)
MAX_TABLE_DEPTH_M = 3.0  # a table seen farther than this is not a useful hint
MAX_AUTO_DISPARITY = 256
DISPARITY_MARGIN_PX = 2  # extra labels beyond the computed window (rounding, pose error)
TOPIC_DEPTH_ESTIMATE = "/reconstruction/depth"  # float32 m, original left view (camera_optical)
TOPIC_RECTIFIED_LEFT = "/reconstruction/rectified_left"
TOPIC_RECTIFIED_RIGHT = "/reconstruction/rectified_right"
TOPIC_DISPARITY = "/reconstruction/disparity"  # colorized, rectified left view
FRAME_RECTIFIED_LEFT = "camera_rectified_left"


@dataclass(frozen=True)
class DisparityPlan:
    """The depth range ``[near, far]`` (m) the matcher covers with disparities 0..max_disparity,
    and where the numbers came from (``source``, for logs and the CLI)."""

    near: float
    far: float
    max_disparity: int
    source: str


@dataclass
class Reconstruction:
    """Everything one pair produced. Images and depth maps are of the rectified left view unless
    named ``original``; points are in ``base`` (metres), colours BGR."""

    pair_index: int
    left_view: int  # recording view index that became the rectified left image
    right_view: int
    swapped: bool  # True when the pair's right view became the left image
    method: str
    plan: DisparityPlan
    rectified: RectifiedPair
    disparity: np.ndarray
    points_base: np.ndarray
    colors: np.ndarray
    depth_truth: np.ndarray | None  # ground truth of the ORIGINAL left view, if recorded
    timestamp_ns: int
    source_pair: Pair = field(repr=False)
    timings_s: dict[str, float] = field(default_factory=dict)

    @cached_property
    def depth_rect(self) -> np.ndarray:
        """Depth (m) of each rectified left pixel along the rectified optical axis."""
        return depth_from_disparity(self.disparity, self.rectified.geometry)

    @cached_property
    def depth_original(self) -> np.ndarray:
        """Depth (m) for each pixel of the original left image (for scoring against truth)."""
        return depth_in_original_view(self.disparity, self.rectified)

    @cached_property
    def disparity_colorized(self) -> np.ndarray:
        """The disparity as a colour image over the searched window (PNG and MCAP share it)."""
        return colorize_disparity(self.disparity, 0, self.plan.max_disparity)

    @property
    def pipeline_time_s(self) -> float:
        """decode + rectify + match + triangulate + write (PLY), what the 0.5 s target counts."""
        stages = ("decode", "rectify", "match", "triangulate", "write")
        return float(sum(self.timings_s.get(k, 0.0) for k in stages))


class _Timer:
    def __init__(self, timings: dict[str, float], stage: str):
        self.timings, self.stage = timings, stage

    def __enter__(self) -> None:
        self.t0 = time.perf_counter()

    def __exit__(self, *exc) -> None:
        self.timings[self.stage] = time.perf_counter() - self.t0


def table_depths(geometry: StereoGeometry, intrinsics: Intrinsics,
                 T_base_camera: np.ndarray) -> np.ndarray | None:
    """Depths (m, along the rectified axis) where the image corners and centre see the plane
    z = 0 of ``base``, or None if any of those rays misses it in front of the camera."""
    w, h = intrinsics.width - 1.0, intrinsics.height - 1.0
    pix = np.array([[0, 0, 1], [w, 0, 1], [0, h, 1], [w, h, 1], [w / 2, h / 2, 1]])
    rays = (T_base_camera[:3, :3] @ np.linalg.solve(intrinsics.K, pix.T)).T
    origin = T_base_camera[:3, 3]
    with np.errstate(divide="ignore", invalid="ignore"):
        t = -origin[2] / rays[:, 2]
    if origin[2] <= 0 or not np.all(np.isfinite(t) & (t > 0)):
        return None
    z = (rays * t[:, None]) @ geometry.R_rect[2]
    return None if np.any(z <= 0) or z.max() > MAX_TABLE_DEPTH_M else z


def plan_disparity(geometry: StereoGeometry, intrinsics: Intrinsics, T_base_camera: np.ndarray, *,
                   near: float | None = None, far: float | None = None,
                   max_disparity: int | str = "auto") -> DisparityPlan:
    """Choose ``[near, far]`` and the matcher's disparity budget (see module docstring).

    ``geometry`` is the rectified geometry before the disparity shift (only fx and the baseline
    are used); ``intrinsics``/``T_base_camera`` are the original left camera's.
    """
    _check_range(near, far)
    fb = geometry.fx * geometry.baseline
    table = table_depths(geometry, intrinsics, T_base_camera)
    source = []
    if far is None:
        far = TABLE_FAR_MARGIN * float(table.max()) if table is not None else DEFAULT_FAR_M
        source.append("far from the table plane" if table is not None else "default far")
    if near is None:
        near = TABLE_NEAR_SHARE * float(table.min()) if table is not None else DEFAULT_NEAR_M
        near = min(near, far / 2.0)
        source.append("near from the table plane" if table is not None else "default near")
    _check_range(near, far)
    needed = fb * (1.0 / near - 1.0 / far)
    limit = min(MAX_AUTO_DISPARITY, geometry.size[0] - 1)
    if max_disparity == "auto":
        n = min(int(math.ceil(needed)) + DISPARITY_MARGIN_PX, limit)
        if n < needed:
            log.warning("depth range %.3f-%.3f m needs %.0f disparities; capped at %d", near,
                        far, needed, n)
        source.append("auto budget")
    else:
        n = int(max_disparity)
        if not 1 <= n <= geometry.size[0] - 1:
            raise ConfigError(f"--max-disparity {n} must be in 1..{geometry.size[0] - 1} "
                              "(the rectified image width - 1)")
        if n < needed:
            log.warning("--max-disparity %d covers depths from %.3f m, not %.3f m", n,
                        fb / (fb / far + n), near)
        source.append("given budget")
    near = fb / (fb / far + n)  # what the budget actually covers
    return DisparityPlan(near=near, far=far, max_disparity=n, source=", ".join(source))


def _fit_budget(plan: DisparityPlan, geometry: StereoGeometry, *, auto: bool) -> DisparityPlan:
    """The matcher needs ``max_disparity < width`` of the final (cropped) rectified canvas."""
    limit = geometry.size[0] - 1
    if plan.max_disparity <= limit:
        return plan
    if not auto:
        raise ConfigError(f"--max-disparity {plan.max_disparity} must be less than the "
                          f"rectified image width {geometry.size[0]}")
    fb = geometry.fx * geometry.baseline
    log.warning("disparity budget cut from %d to %d by the rectified width", plan.max_disparity,
                limit)
    return replace(plan, max_disparity=limit, near=fb / (fb / plan.far + limit))


def _check_range(near: float | None, far: float | None) -> None:
    for name, v in (("near", near), ("far", far)):
        if v is not None and not (math.isfinite(v) and v > 0):
            raise ConfigError(f"--{name} must be a positive distance in metres, got {v}")
    if near is not None and far is not None and near >= far:
        raise ConfigError(f"--near {near} must be less than --far {far}")


def _view_inputs(pair: Pair, which: str):
    """(image, intrinsics, T_base_camera) of one view, or RecordingError naming what is missing."""
    view = getattr(pair, which)
    T = getattr(view, "T_base_camera", None)
    if T is None or np.shape(T) != (4, 4) or not np.all(np.isfinite(T)):
        raise RecordingError(f"pair {pair.index}: view {view.index} has no camera pose")
    intr = getattr(view, "intrinsics", None)
    if intr is None:
        raise RecordingError(f"pair {pair.index}: view {view.index} has no camera calibration")
    image = view.image
    if image is None or np.size(image) == 0:
        raise RecordingError(f"pair {pair.index}: view {view.index} has no image")
    if (image.shape[1], image.shape[0]) != intr.size:
        raise RecordingError(f"pair {pair.index}: view {view.index} image is "
                             f"{image.shape[1]}x{image.shape[0]} but its calibration is "
                             f"{intr.width}x{intr.height}")
    return image, intr, np.asarray(T, dtype=float)


def reconstruct_pair(pair: Pair, *, method: str = "birchfield", max_disparity: int | str = "auto",
                     near: float | None = None, far: float | None = None,
                     stereo_options: dict | None = None) -> Reconstruction:
    """Rectify, match and triangulate one recorded pair (``armstereo.recording.Pair``).

    Raises RecordingError for a pair without poses, calibration or images, ConfigError for bad
    options and StereoError when the geometry cannot be rectified.
    """
    if method not in METHODS:
        raise ConfigError(f"--method must be one of {', '.join(METHODS)}, got {method!r}")
    timings: dict[str, float] = {}
    with _Timer(timings, "decode"):
        img1, intr1, T1 = _view_inputs(pair, "left")
        img2, intr2, T2 = _view_inputs(pair, "right")
    with _Timer(timings, "rectify"):
        geometry0, swapped = rectified_geometry(intr1, T1, intr2, T2)
        left_intr, T_left = (intr2, T2) if swapped else (intr1, T1)
        plan = plan_disparity(geometry0, left_intr, T_left, near=near, far=far,
                              max_disparity=max_disparity)
        rect = rectify_pair(img1, img2, intr1.K, intr1.dist, T1, intr2.K, intr2.dist, T2,
                            depth_range=(plan.near, plan.far))
        plan = _fit_budget(plan, rect.geometry, auto=max_disparity == "auto")
    log.debug("pair %d: left = view %d%s, rotation %.0f deg, baseline %.1f mm, depth %.3f-%.3f m "
             "-> disparities 0..%d (%s)", pair.index,
             (pair.right if swapped else pair.left).index, " (swapped)" if swapped else "",
             rect.rotation_deg, rect.baseline * 1000, plan.near, plan.far, plan.max_disparity,
             plan.source)
    with _Timer(timings, "match"):
        disparity = compute_disparity(rect.left, rect.right, plan.max_disparity, method=method,
                                      min_disparity=0, left_mask=rect.left_mask,
                                      right_mask=rect.right_mask, **(stereo_options or {}))
    with _Timer(timings, "triangulate"):
        points, colors = point_cloud(disparity, rect.geometry, rect.left)
    left, right = (pair.right, pair.left) if swapped else (pair.left, pair.right)
    return Reconstruction(
        pair_index=pair.index, left_view=left.index, right_view=right.index, swapped=swapped,
        method=method, plan=plan, rectified=rect, disparity=disparity,
        points_base=points, colors=colors, depth_truth=getattr(left, "depth", None),
        timestamp_ns=int(left.timestamp_ns), timings_s=timings, source_pair=pair)


def output_paths(out_dir: str | Path, prefix: str) -> dict[str, Path]:
    """Where :func:`write_outputs` puts each product."""
    out = Path(out_dir)
    return {"ply": out / f"{prefix}.ply", "depth": out / f"{prefix}_depth.png",
            "disparity": out / f"{prefix}_disparity.png",
            "rectified": out / f"{prefix}_rectified.png",
            "depth_error": out / f"{prefix}_depth_error.png", "mcap": out / f"{prefix}.mcap"}


def write_outputs(recon: Reconstruction, out_dir: str | Path, prefix: str, *,
                  metadata: dict[str, str] | None = None) -> dict[str, Path]:
    """Write the PLY, the depth PNG (mm, original left view), the colorized disparity, the
    rectified pair with epipolar lines, the depth-error map (when ground truth exists) and the
    reconstruction MCAP. Returns the written paths by kind; adds ``write``/``write_extras`` to
    ``recon.timings_s``."""
    out = Path(out_dir)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise ConfigError(f"cannot create output folder {out}: {err.strerror}") from err
    paths = output_paths(out, prefix)
    written: dict[str, Path] = {}
    with _Timer(recon.timings_s, "write"):
        written["ply"] = write_ply(paths["ply"], recon.points_base, recon.colors,
                                   comment=f"armstereo pair {recon.pair_index}, frame base, "
                                           "metres")
    with _Timer(recon.timings_s, "write_extras"):
        written["depth"] = write_depth_png(paths["depth"], recon.depth_original)
        written["disparity"] = write_png(paths["disparity"], recon.disparity_colorized)
        written["rectified"] = write_png(paths["rectified"],
                                         side_by_side(recon.rectified.left,
                                                      recon.rectified.right))
        if recon.depth_truth is not None:
            written["depth_error"] = write_png(paths["depth_error"],
                                               depth_error_map(recon.depth_original,
                                                               recon.depth_truth))
        written["mcap"] = write_reconstruction_mcap(recon, paths["mcap"], metadata=metadata)
    return written


def write_reconstruction_mcap(recon: Reconstruction, path: str | Path, *,
                              metadata: dict[str, str] | None = None) -> Path:
    """An MCAP that Foxglove shows as arm + camera + cloud, and that reads back as a recording.

    ``metadata`` (str -> str, e.g. the source recording's robot and URDF hash) is stored with
    the reconstruction's own keys (kind, pair, method, depth range, ...), which take precedence.

    Holds the calibration, both source views as recorded (image, ground-truth depth, /tf,
    joints, the pair event), the cloud on ``/points`` (base frame), the estimated depth of the
    original left view on ``/reconstruction/depth`` and the rectified images and colorized
    disparity on ``/reconstruction/*``.
    """
    pair = recon.source_pair
    views = [pair.left, pair.right]
    t_cloud = max(int(v.timestamp_ns) for v in views)
    meta = {**(metadata or {}), "kind": "reconstruction", "pair": str(recon.pair_index),
            "method": recon.method, "left_view": str(recon.left_view),
            "near_m": f"{recon.plan.near:.6g}", "far_m": f"{recon.plan.far:.6g}",
            "max_disparity": str(recon.plan.max_disparity),
            "points": str(len(recon.points_base))}
    left = pair.right if recon.swapped else pair.left
    with RecordingWriter(path, metadata=meta) as w:
        w.write_calibration(left.intrinsics, min(int(v.timestamp_ns) for v in views))
        for v in views:
            names = tuple(v.joint_names or ())
            q = np.zeros(0) if v.joint_positions is None else v.joint_positions
            w.write_view(v.index, Frame(v.image, int(v.timestamp_ns), v.depth), q,
                         names if len(names) == len(q) else (), v.T_base_flange,
                         v.T_flange_camera, settle_s=float(v.settle_s or 0.0))
        w.write_pair(pair.index, pair.left.index, pair.right.index,
                     pair.commanded_baseline_m, pair.achieved_baseline_m, pair.direction)
        t_left = int(left.timestamp_ns)
        w.write_depth(recon.depth_original, t_left, topic=TOPIC_DEPTH_ESTIMATE)
        w.write_image(TOPIC_RECTIFIED_LEFT, recon.rectified.left, t_left,
                      frame_id=FRAME_RECTIFIED_LEFT)
        w.write_image(TOPIC_RECTIFIED_RIGHT, recon.rectified.right, t_left,
                      frame_id=FRAME_RECTIFIED_LEFT)
        w.write_image(TOPIC_DISPARITY, recon.disparity_colorized, t_left,
                      frame_id=FRAME_RECTIFIED_LEFT)
        w.write_point_cloud(recon.points_base, recon.colors, t_cloud)
    return Path(path)
