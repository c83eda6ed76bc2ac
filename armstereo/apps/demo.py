"""The demo: mock UR5e + mock camera -> recording -> reconstruction -> score against truth.

Everything runs on the embedded mock backends (simulated clock), so it needs no hardware. By
default the mock errs like real hardware (the ``realistic`` profile, see docs/mock-profiles.md):
the demo reads the arm's calibrated kinematics from its broadcast, captures with them, checks
the recording (our FK against the controller's pose), reconstructs and scores. The report's
accuracy is measured on the left view's pixels that have ground truth and are seen by the right
view too (see :mod:`armstereo.evaluation.depth`); ``point_error_mm`` is the distance of the
reconstructed points (base frame) to the scene's true surfaces.
"""

from __future__ import annotations

import json
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from armstereo import __version__, backends
from armstereo.capture import CaptureSettings, plan_capture
from armstereo.capture.plan import validate_settings
from armstereo.capture.run import model_metadata
from armstereo.capture.session import capture_to_file
from armstereo.errors import ConfigError, RecordingError
from armstereo.evaluation.depth import DepthAccuracy, score_depth, visible_mask
from armstereo.evaluation.scene_truth import SceneTruth
from armstereo.io.files import write_text_atomic
from armstereo.mount import CameraMount
from armstereo.reconstruct.outputs import write_outputs
from armstereo.reconstruct.pipeline import reconstruct_pair
from armstereo.reconstruct.stereo_options import (
    CLEAN_PHOTO_CHECK,
    BirchfieldOptions,
    StereoOptions,
    matcher_record,
    options_for,
    resolve_matcher,
)
from armstereo.recording import Recording
from armstereo.recording.inspect import summarize
from armstereo.robot.arm_model import ArmModel
from armstereo.robot.model_file import load_arm_model
from armstereo.robot.source import CaptureKinematics, choose_kinematics
from armstereo.scene.export import analyze_points

DEFAULT_BASELINE_M = 0.08
DEMO_FILES = ("demo.mcap", "points.ply", "disparity.png", "rectified.png", "depth_error.png",
              "report.json", "reconstruction.mcap", "scene")


@dataclass(frozen=True)
class DemoOptions:
    """What the demo captures and how it matches. Lengths in metres."""

    robot: str = "ur5e"
    baseline: float = DEFAULT_BASELINE_M
    method: str | None = None  # None: ``stereo``'s method, else "birchfield"
    seed: int = 0
    # Grey levels of extra Gaussian noise; None: 1.0 on the ideal profile (a real sensor is
    # never noise free), 0 on the others (their image effects carry the sensor's noise).
    camera_noise: float | None = None
    joint_noise: float = 0.0
    profile: Any = "realistic"  # a mock profile name (or a drivers.mock.profile.MockProfile)
    read_calibration: bool = True  # use the table the arm broadcasts (False: nominal model)
    # What the software believes about the camera (None: the bundled mount file, which the
    # mock's true camera differs from by the profile's errors).
    mount: CameraMount | None = None
    # Options of the matcher: an options object, or the older dict of its keywords; None:
    # the profile's choice (see :meth:`matcher`).
    stereo_options: dict | None = None
    stereo: StereoOptions | None = None

    def __post_init__(self) -> None:
        if self.method is None:  # frozen: set once, here
            object.__setattr__(self, "method", getattr(self.stereo, "method", "birchfield"))

    @property
    def profile_name(self) -> str:
        return getattr(self.profile, "name", self.profile)

    def matcher(self) -> StereoOptions:
        """How the demo matches: ``stereo`` or ``stereo_options`` if given; else, on the ideal
        profile with Birchfield-Tomasi, the photo-consistency check for clean views (both views
        see the same intensities there, so a match that does not look alike is the foreground
        carried across a depth edge: bench/results/footprint.md), else the defaults.
        ConfigError for options of another method than ``method``."""
        if self.stereo is not None or self.stereo_options is not None:
            return resolve_matcher(self.method, self.stereo, self.stereo_options,
                                   error=ConfigError)
        if self.profile_name == "ideal" and self.method == "birchfield":
            return BirchfieldOptions(photo_check=CLEAN_PHOTO_CHECK)
        return options_for(self.method, error=ConfigError)

    def matcher_options(self) -> dict:
        """The matcher's options beyond its defaults, by name (``stereo_options`` as given)."""
        if self.stereo_options is not None:
            return dict(self.stereo_options)
        return self.matcher().non_defaults()


def demo_settings(options: DemoOptions) -> CaptureSettings:
    """The demo's capture settings; raises ConfigError for an out-of-range option, so callers
    can check before they make a folder or show progress."""
    settings = CaptureSettings(baseline=options.baseline, direction=np.array([1.0, 0.0, 0.0]),
                               pairs=1)
    validate_settings(settings)
    options.matcher()  # the matcher's options are checked here too
    return settings


def run_demo(out_dir: Path, options: DemoOptions = DemoOptions(),
             progress: Callable[[str], None] = lambda s: None) -> dict:
    """Capture, reconstruct, write the demo files into ``out_dir`` and return the report."""
    settings = demo_settings(options)
    t_start = time.perf_counter()
    timings: dict[str, float] = {}

    progress(f"[1/7] connecting the mock {options.robot.upper()} ({options.profile_name} "
             f"profile) and reading its calibration")
    t0 = time.perf_counter()
    world_mount = CameraMount.load(None)
    given = load_arm_model(options.robot, mount=world_mount)
    noise = options.camera_noise
    if noise is None:
        noise = 1.0 if options.profile_name == "ideal" else 0.0
    arm_config = backends.arm_config("mock", joint_noise=options.joint_noise, seed=options.seed,
                                     profile=options.profile)
    camera_config = backends.camera_config("mock", noise=noise, seed=options.seed,
                                           profile=options.profile, truth_mount=world_mount)
    with backends.build_arm("mock", arm_config, given) as arm:
        kinematics = _kinematics(given, arm, options)
        model = kinematics.model
        progress(f"[2/7] capturing a pair (baseline {options.baseline * 1000:.0f} mm) with "
                 f"{kinematics.source} kinematics")
        plan = plan_capture(model, arm.joint_positions(), settings)
        with backends.build_camera("mock", camera_config, model, arm) as camera:
            capture_to_file(arm, camera, model, plan, out_dir / "demo.mcap",
                            {**model_metadata(model), **kinematics.metadata(), "arm": "mock",
                             "camera": "mock", "baseline_m": repr(options.baseline),
                             "direction": "x", "pairs": "1", "source": "armstereo demo",
                             "mock_profile": options.profile_name},
                            progress=None)
    timings["capture"] = time.perf_counter() - t0

    progress("[3/7] checking the recording")
    recording = Recording.open(out_dir / "demo.mcap")
    check = summarize(recording)
    pair = recording[0]

    progress(f"[4/7] rectifying and matching ({options.method}; the first run compiles the "
             "matcher, later runs reuse the cache)")
    recon = reconstruct_pair(pair, stereo=options.matcher())
    timings.update({k: recon.timings_s[k] for k in ("decode", "rectify", "match",
                                                    "triangulate")})

    progress("[5/7] writing the point cloud and images")
    t0 = time.perf_counter()
    _write_products(recon, out_dir)
    timings["write"] = time.perf_counter() - t0

    progress("[6/7] scoring against the mock camera's ground truth")
    t0 = time.perf_counter()
    accuracy = score_reconstruction(recon.depth_original, pair, swapped=recon.swapped)
    point_error = point_error_mm(recon.points_base, recording.metadata)
    timings["score"] = time.perf_counter() - t0

    progress("[7/7] finding the table and the objects on it")
    t0 = time.perf_counter()
    truth = SceneTruth.from_json(recording.metadata["scene_truth"])
    analysis, scene_score = analyze_points(recon.points_base, recon.colors_bgr,
                                           out_dir / "scene", source="armstereo demo",
                                           truth=truth)
    timings["scene"] = time.perf_counter() - t0
    timings["total"] = time.perf_counter() - t_start
    report = _report(recon, accuracy, timings, options)
    report["scene"] = {"objects": analysis.as_dict()["objects"],
                       "score": scene_score.as_dict()}
    report.update(profile=options.profile_name, point_error_mm=point_error,
                  kinematics=_kinematics_report(kinematics, arm),
                  check={"fk_vs_controller_max_mm": check["fk_vs_controller_max_mm"],
                         "warnings": check["warnings"]},
                  error_budget={"sources": _sources(options),
                                "median_abs_rel_depth_error":
                                    accuracy.median_abs_rel_depth_error,
                                "median_point_error_mm": point_error["median"],
                                "table": ERROR_BUDGET_TABLE})
    write_text_atomic(out_dir / "report.json", json.dumps(report, indent=2) + "\n")
    return report


ERROR_BUDGET_TABLE = "bench/results/error_budget.md"
POINT_ERROR_SAMPLES = 50_000  # points scored against the scene truth (every k-th point)


def _kinematics(given: ArmModel, arm, options: DemoOptions) -> CaptureKinematics:
    """The kinematics the capture uses: the arm's broadcast table (read like a UR's), or the
    model given when ``read_calibration`` is off; then the software's mount."""
    chosen = (choose_kinematics(given, arm, live=False) if options.read_calibration
              else CaptureKinematics(given, "nominal"))
    mount = options.mount or CameraMount.load(None)
    model = chosen.model
    model = (ArmModel.from_dh(model.dh, mount=mount) if model.dh is not None
             else ArmModel.load(model.name, mount=mount))
    return CaptureKinematics(model, chosen.source, chosen.warnings)


def _kinematics_report(kinematics: CaptureKinematics, arm) -> dict:
    read = getattr(arm, "kinematics", None)
    diff = getattr(read, "nominal_difference", None)
    return {"source": kinematics.source,
            "dh_sha256": kinematics.model.dh.sha256 if kinematics.model.dh else None,
            "nominal_vs_calibrated_workspace_max": None if diff is None else
            {"translation_mm": diff.translation_mm, "rotation_deg": diff.rotation_deg},
            "warnings": list(kinematics.warnings)}


def _sources(options: DemoOptions) -> list[str]:
    """The error sources switched on in this run (names as in the error budget table)."""
    p = backends.arm_config("mock", profile=options.profile).profile
    out = []
    if p.kinematics:
        out.append("kinematics (calibrated arm)" + ("" if options.read_calibration
                                                    else ", nominal model used"))
    if p.hand_eye.translation_m > 0 or p.hand_eye.rotation_rad > 0:
        out.append("hand-eye error")
    if p.intrinsics.focal_rel > 0 or p.intrinsics.principal_px > 0 or p.intrinsics.radial > 0:
        out.append("intrinsics error")
    if p.image.any:
        out.append("image effects")
    if p.joints.any:
        out.append("joint noise")
    return out


def point_error_mm(points_base: np.ndarray, metadata: dict[str, str]) -> dict:
    """Distance (mm) of reconstructed points (N, 3, base frame) to the recorded scene truth's
    surfaces: median, 90th percentile and the share within 1 mm; None values without truth."""
    text = metadata.get("scene_truth")
    if not text or len(points_base) == 0:
        return {"median": None, "p90": None, "within_1mm": None}
    step = max(1, len(points_base) // POINT_ERROR_SAMPLES)  # a fixed stride: reproducible
    dist = SceneTruth.from_json(text).distance(points_base[::step]) * 1000.0
    return {"median": float(np.median(dist)), "p90": float(np.percentile(dist, 90)),
            "within_1mm": float(np.mean(dist <= 1.0))}


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
        # options passed to the matcher beyond its defaults (e.g. the ideal profile's check)
        "matcher_options": options.matcher_options(),
        "matcher": matcher_record(recon.stereo),  # every option: how to match it again
        "disparity_range_px": [0, int(recon.window.max_disparity)],
        "depth_range_m": [round(recon.window.near, 4), round(recon.window.far, 4)],
        "robot": options.robot,
        "armstereo_version": __version__,
    }
