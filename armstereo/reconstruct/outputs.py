"""Write what a reconstruction produced: PLY, depth and disparity PNGs, the rectified pair with
epipolar lines, a depth-error map (with ground truth) and an MCAP for Foxglove.

Every file is written atomically (a killed run leaves old files or none, never half of one).
"""

from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np

from armstereo.errors import OutputError
from armstereo.frame import Frame
from armstereo.io.images import depth_error_map, side_by_side, write_depth_png, write_png
from armstereo.io.ply import write_ply
from armstereo.reconstruct.pipeline import PairReconstruction
from armstereo.reconstruct.stereo_options import matcher_record
from armstereo.recording import RecordingWriter
from armstereo.recording import schemas as S


def output_paths(out_dir: str | Path, prefix: str) -> dict[str, Path]:
    """Where :func:`write_outputs` puts each product."""
    out = Path(out_dir)
    return {"ply": out / f"{prefix}.ply", "depth": out / f"{prefix}_depth.png",
            "disparity": out / f"{prefix}_disparity.png",
            "rectified": out / f"{prefix}_rectified.png",
            "depth_error": out / f"{prefix}_depth_error.png", "mcap": out / f"{prefix}.mcap"}


def write_outputs(recon: PairReconstruction, out_dir: str | Path, prefix: str, *,
                  metadata: dict[str, str] | None = None,
                  paths: dict[str, Path] | None = None) -> dict[str, Path]:
    """Write the PLY, the depth PNG (mm, original left view), the colorized disparity, the
    rectified pair with epipolar lines, the depth-error map (when ground truth exists) and the
    reconstruction MCAP, to :func:`output_paths` or to ``paths`` (by kind; a kind left out is
    not written). Returns the written paths by kind; adds ``write`` (the PLY) and
    ``write_extras`` to ``recon.timings_s``."""
    out = Path(out_dir)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise OutputError(f"cannot create output folder {out}: {err.strerror}") from None
    paths = output_paths(out, prefix) if paths is None else paths
    products = {
        "depth": lambda p: write_depth_png(p, recon.depth_original),
        "disparity": lambda p: write_png(p, recon.disparity_colorized),
        "rectified": lambda p: write_png(p, side_by_side(recon.rectified.left,
                                                         recon.rectified.right)),
        "depth_error": lambda p: (None if recon.depth_truth is None else write_png(
            p, depth_error_map(recon.depth_original, recon.depth_truth))),
        "mcap": lambda p: write_reconstruction_mcap(recon, p, metadata=metadata),
    }
    written: dict[str, Path] = {}
    t0 = time.perf_counter()
    if "ply" in paths:
        written["ply"] = write_ply(paths["ply"], recon.points_base, recon.colors_bgr,
                                   comment=f"armstereo pair {recon.pair_index}, frame base, "
                                           "metres")
    t1 = time.perf_counter()
    for kind, write in products.items():
        if kind in paths and (path := write(paths[kind])) is not None:
            written[kind] = path
    recon.timings_s.update(write=t1 - t0, write_extras=time.perf_counter() - t1)
    return written


def write_reconstruction_mcap(recon: PairReconstruction, path: str | Path, *,
                              metadata: dict[str, str] | None = None) -> Path:
    """An MCAP that Foxglove shows as arm + camera + cloud, and that reads back as a recording.

    ``metadata`` (str -> str, e.g. the source recording's robot and URDF hash) is stored with
    the reconstruction's own keys (kind, pair, method, depth range, ..., ``matcher``: the JSON
    of :func:`~armstereo.reconstruct.stereo_options.matcher_record`), which take precedence.

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
            "near_m": f"{recon.window.near:.6g}", "far_m": f"{recon.window.far:.6g}",
            "max_disparity": str(recon.window.max_disparity),
            "points": str(len(recon.points_base)),
            "matcher": json.dumps(matcher_record(recon.stereo))}
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
        w.write_depth(recon.depth_original, t_left, topic=S.TOPIC_DEPTH_ESTIMATE)
        w.write_image(S.TOPIC_RECTIFIED_LEFT, recon.rectified.left, t_left,
                      frame_id=S.FRAME_RECTIFIED_LEFT)
        w.write_image(S.TOPIC_RECTIFIED_RIGHT, recon.rectified.right, t_left,
                      frame_id=S.FRAME_RECTIFIED_LEFT)
        w.write_image(S.TOPIC_DISPARITY, recon.disparity_colorized, t_left,
                      frame_id=S.FRAME_RECTIFIED_LEFT)
        w.write_point_cloud(recon.points_base, recon.colors_bgr, t_cloud)
    return Path(path)
