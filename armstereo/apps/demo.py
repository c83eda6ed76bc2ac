"""The demo: mock UR5e + mock camera -> recording -> reconstruction -> score against truth.

Everything runs on the embedded mock backends (simulated clock), so it needs no hardware. The
report's accuracy is measured on the left view's pixels that have ground truth and are seen by
the right view too (see :mod:`armstereo.evaluation.depth`).
"""

from __future__ import annotations

import json
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from armstereo import __version__, backends
from armstereo.capture import CaptureSettings, plan_capture
from armstereo.capture.plan import validate_settings
from armstereo.capture.run import model_metadata
from armstereo.capture.session import capture_to_file
from armstereo.errors import RecordingError
from armstereo.evaluation.depth import DepthAccuracy, score_depth, visible_mask
from armstereo.evaluation.scene_truth import SceneTruth
from armstereo.io.files import write_text_atomic
from armstereo.kinematics import ArmModel
from armstereo.mount import CameraMount
from armstereo.reconstruct.outputs import write_outputs
from armstereo.reconstruct.pipeline import reconstruct_pair
from armstereo.recording import Recording
from armstereo.scene.export import analyze_points

DEFAULT_BASELINE_M = 0.08
DEMO_FILES = ("demo.mcap", "points.ply", "disparity.png", "rectified.png", "depth_error.png",
              "report.json", "reconstruction.mcap", "scene")


@dataclass(frozen=True)
class DemoOptions:
    """What the demo captures and how it matches. Lengths in metres."""

    robot: str = "ur5e"
    baseline: float = DEFAULT_BASELINE_M
    method: str = "birchfield"
    seed: int = 0
    camera_noise: float = 1.0  # grey levels: a real sensor is never noise free
    joint_noise: float = 0.0


def demo_settings(options: DemoOptions) -> CaptureSettings:
    """The demo's capture settings; raises ConfigError for an out-of-range option, so callers
    can check before they make a folder or show progress."""
    settings = CaptureSettings(baseline=options.baseline, direction=np.array([1.0, 0.0, 0.0]),
                               pairs=1)
    validate_settings(settings)
    return settings


def run_demo(out_dir: Path, options: DemoOptions = DemoOptions(),
             progress: Callable[[str], None] = lambda s: None) -> dict:
    """Capture, reconstruct, write the demo files into ``out_dir`` and return the report."""
    settings = demo_settings(options)
    t_start = time.perf_counter()
    timings: dict[str, float] = {}

    progress(f"[1/5] capturing a pair with the mock {options.robot.upper()} "
             f"(baseline {options.baseline * 1000:.0f} mm)")
    t0 = time.perf_counter()
    model = ArmModel.load(options.robot, mount=CameraMount.load(None))
    arm_config = backends.arm_config("mock", joint_noise=options.joint_noise, seed=options.seed)
    camera_config = backends.camera_config("mock", noise=options.camera_noise, seed=options.seed,
                                           scene=backends.mock_table_scene(options.seed))
    with backends.build_arm("mock", arm_config, model) as arm:
        plan = plan_capture(model, arm.joint_positions(), settings)
        with backends.build_camera("mock", camera_config, model, arm) as camera:
            capture_to_file(arm, camera, model, plan, out_dir / "demo.mcap",
                            {**model_metadata(model), "arm": "mock",
                             "camera": "mock", "baseline_m": repr(options.baseline),
                             "direction": "x", "pairs": "1", "source": "armstereo demo"},
                            progress=None)
    timings["capture"] = time.perf_counter() - t0

    progress(f"[2/5] rectifying and matching ({options.method}; the first run compiles the "
             "matcher, later runs reuse the cache)")
    pair = Recording.open(out_dir / "demo.mcap")[0]
    recon = reconstruct_pair(pair, method=options.method)
    timings.update({k: recon.timings_s[k] for k in ("decode", "rectify", "match",
                                                    "triangulate")})

    progress("[3/5] writing the point cloud and images")
    t0 = time.perf_counter()
    _write_products(recon, out_dir)
    timings["write"] = time.perf_counter() - t0

    progress("[4/5] scoring against the mock camera's ground truth")
    t0 = time.perf_counter()
    accuracy = score_reconstruction(recon.depth_original, pair, swapped=recon.swapped)
    timings["score"] = time.perf_counter() - t0

    progress("[5/5] finding the table and the objects on it")
    t0 = time.perf_counter()
    truth = SceneTruth.from_json(Recording.open(out_dir / "demo.mcap").metadata["scene_truth"])
    analysis, scene_score = analyze_points(recon.points_base, recon.colors_bgr,
                                           out_dir / "scene", source="armstereo demo",
                                           truth=truth)
    timings["scene"] = time.perf_counter() - t0
    timings["total"] = time.perf_counter() - t_start
    report = _report(recon, accuracy, timings, options)
    report["scene"] = {"objects": analysis.as_dict()["objects"],
                       "score": scene_score.as_dict()}
    write_text_atomic(out_dir / "report.json", json.dumps(report, indent=2) + "\n")
    return report


def _write_products(recon, out_dir: Path) -> None:
    names = {"ply": "points.ply", "disparity": "disparity.png", "rectified": "rectified.png",
             "depth_error": "depth_error.png", "mcap": "reconstruction.mcap"}
    write_outputs(recon, out_dir, "demo", paths={k: out_dir / v for k, v in names.items()})


def score_reconstruction(depth, pair, *, swapped: bool = False) -> DepthAccuracy:
    """Score ``depth`` (m, the original view that became the rectified left image) against
    that view's recorded ground truth, on pixels the other view sees too."""
    left, right = (pair.right, pair.left) if swapped else (pair.left, pair.right)
    if left.depth is None or right.depth is None:
        raise RecordingError(f"pair {pair.index} has no ground-truth depth (not a mock capture)")
    mask = visible_mask(left.depth, left.intrinsics, left.T_base_camera, right.depth,
                        right.intrinsics, right.T_base_camera)
    return score_depth(depth, left.depth, mask)


def _report(recon, accuracy, timings: dict[str, float], options: DemoOptions) -> dict:
    return {
        "points": int(len(recon.points_base)),
        "timings_s": {k: round(v, 4) for k, v in timings.items()},
        "accuracy": accuracy.as_dict(),
        "baseline_m": options.baseline,
        "method": options.method,
        "disparity_range_px": [0, int(recon.window.max_disparity)],
        "depth_range_m": [round(recon.window.near, 4), round(recon.window.far, 4)],
        "robot": options.robot,
        "armstereo_version": __version__,
    }
