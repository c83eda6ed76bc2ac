"""The demo: the whole workflow on the mock cell, scored against ground truth.

What a user with a UR arm and a new camera does, on the embedded mock backends (simulated
clock, no hardware): calibrate the camera on the cell (``armstereo calibrate``: views of a
board, the mount file it writes, :func:`armstereo.apps.calibrate.calibrate_mock_cell`), then
capture the desk with that mount file (the arm's calibrated kinematics read from its
broadcast, as ``capture`` does), check the recording, reconstruct it (photometric correction
from the mount file's vignetting, :mod:`armstereo.photometric`), score it and find the table
and the objects on it. The same pair reconstructed with the bundled mount file, as a user who
skipped the calibration would, gives the "before" figures. By default the mock errs like real
hardware (the ``realistic`` profile, see docs/mock-profiles.md); profile and seed name one
cell (:mod:`drivers.mock.cell`), so calibration and capture meet the same camera.

Scores: :mod:`armstereo.apps.demo_score`.
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
from armstereo.apps.calibrate import MockCalibration, calibrate_mock_cell
from armstereo.apps.demo_score import (
    compare_mount,
    point_error_mm,
    score_reconstruction,
)
from armstereo.capture import CaptureSettings, plan_capture
from armstereo.capture.plan import validate_settings
from armstereo.capture.run import model_metadata
from armstereo.capture.session import capture_to_file
from armstereo.errors import ConfigError
from armstereo.evaluation.scene_truth import SceneTruth
from armstereo.io.files import write_text_atomic
from armstereo.mount import CameraMount
from armstereo.photometric.correct import as_options, for_recording, record_json
from armstereo.reconstruct import warmup
from armstereo.reconstruct.outputs import write_outputs
from armstereo.reconstruct.pipeline import reconstruct_pair
from armstereo.reconstruct.stereo_options import (
    CLEAN_PHOTO_CHECK,
    BirchfieldOptions,
    SgbmOptions,
    StereoOptions,
    matcher_record,
    options_for,
    resolve_matcher,
)
from armstereo.recording import Recording
from armstereo.recording.inspect import summarize
from armstereo.recording.remount import remounted
from armstereo.robot.arm_model import ArmModel
from armstereo.robot.model_file import load_arm_model
from armstereo.robot.source import CaptureKinematics, choose_kinematics
from armstereo.scene.export import analyze_points

__all__ = ["DEFAULT_BASELINE_M", "DEMO_FILES", "DEMO_SGBM", "DemoOptions", "demo_settings",
           "point_error_mm", "run_demo", "score_reconstruction"]

DEFAULT_BASELINE_M = 0.08
DEMO_FILES = ("demo.mcap", "points.ply", "disparity.png", "rectified.png", "depth_error.png",
              "report.json", "reconstruction.mcap", "scene", "camera.toml", "calibration.mcap",
              "calibration.json")
DEMO_BOARD = "chessboard:17x12:0.016"
# Views of the demo's calibration: few, for a quick first run; 4 put the board into the image
# corners (distortion and vignetting are largest there). bench/cell.py measures them.
DEMO_CALIBRATION_VIEWS = 10
DEMO_CORNER_VIEWS = 4
# SGBM in the demo: both images blurred (sigma 1 px) and the match averaged over 4 quarter-
# pixel shifts of the right image, against the sensor noise and the parabola's locking to whole
# disparities. On the realistic cell, calibrated: median depth error 0.263 -> 0.126 % over
# seeds 0-4 (held out 0.301 -> 0.135 %), density 86.7 -> 87.9 % (85.7 -> 86.7 %), about 4x the
# matching time (bench/results/sgbm_desk.md). Not SgbmOptions' defaults: the blur costs bad-2
# on the clean Middlebury pairs (4.04 -> 4.23 %), and the peer of the matcher benchmarks stays
# OpenCV's SGBM as its users know it.
DEMO_SGBM = SgbmOptions(presmooth=1.0, shifts=4)


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
    # What the software believes about the camera. None: calibrate the camera on the cell
    # first and use the mount file that writes (``calibrate``), or the bundled mount file
    # when ``calibrate`` is False.
    mount: CameraMount | None = None
    # Options of the matcher: an options object, or the older dict of its keywords; None:
    # the profile's choice (see :meth:`matcher`).
    stereo_options: dict | None = None
    stereo: StereoOptions | None = None
    # None: calibrate unless ``mount`` is given. The calibration: board, views, corner views.
    calibrate: bool | None = None
    board: str = DEMO_BOARD
    calibration_views: int = DEMO_CALIBRATION_VIEWS
    corner_views: int = DEMO_CORNER_VIEWS
    # What is corrected before matching (armstereo.photometric); the vignetting model is the
    # mount file's.
    photometric: Any = True
    # Also reconstruct the pair with the bundled mount file (the "before" figures).
    compare: bool = True

    def __post_init__(self) -> None:
        if self.method is None:  # frozen: set once, here
            object.__setattr__(self, "method", getattr(self.stereo, "method", "birchfield"))

    @property
    def calibrates(self) -> bool:
        return self.mount is None if self.calibrate is None else bool(self.calibrate)

    @property
    def profile_name(self) -> str:
        return getattr(self.profile, "name", self.profile)

    def matcher(self) -> StereoOptions:
        """How the demo matches: ``stereo`` or ``stereo_options`` if given; else, on the ideal
        profile with Birchfield-Tomasi, the photo-consistency check for clean views (both views
        see the same intensities there, so a match that does not look alike is the foreground
        carried across a depth edge: bench/results/footprint.md); with SGBM :data:`DEMO_SGBM`;
        else the defaults. ConfigError for options of another method than ``method``."""
        if self.stereo is not None or self.stereo_options is not None:
            return resolve_matcher(self.method, self.stereo, self.stereo_options,
                                   error=ConfigError)
        if self.profile_name == "ideal" and self.method == "birchfield":
            return BirchfieldOptions(photo_check=CLEAN_PHOTO_CHECK)
        if self.method == "sgbm":
            return DEMO_SGBM
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
    as_options(options.photometric)
    if options.calibrates:
        from armstereo.calibration.board import parse_board
        from armstereo.calibration.checks import MIN_VIEWS
        from armstereo.calibration.views import MAX_VIEWS

        parse_board(options.board)
        if not MIN_VIEWS <= options.calibration_views <= MAX_VIEWS:
            raise ConfigError(f"calibration views must be in {MIN_VIEWS}..{MAX_VIEWS}, got "
                              f"{options.calibration_views}")
        if options.corner_views < 0:
            raise ConfigError(f"corner views must be >= 0, got {options.corner_views}")
    return settings


def run_demo(out_dir: Path, options: DemoOptions = DemoOptions(),
             progress: Callable[[str], None] = lambda s: None) -> dict:
    """Calibrate (unless told not to), capture, reconstruct, write the demo files into
    ``out_dir`` and return the report (also ``report.json``)."""
    settings = demo_settings(options)
    t_start = time.perf_counter()
    timings: dict[str, float] = {}
    n = 8 if options.calibrates else 7
    compiling = warmup.start(options.method, options.matcher_options())
    try:
        return _run(out_dir, options, settings, n, timings, t_start, compiling, progress)
    finally:
        warmup.wait(compiling)


def _run(out_dir, options, settings, n, timings, t_start, compiling, progress) -> dict:
    step = _Steps(n, progress)
    step(f"connecting the mock {options.robot.upper()} ({options.profile_name} profile, seed "
         f"{options.seed}) and reading its calibration")
    bundled = CameraMount.load(None)
    calibration = None
    if options.calibrates:
        _precheck(options, settings, bundled)  # a refused capture must not cost a calibration
        step(f"calibrating the camera: {options.calibration_views} views of {options.board} "
             f"-> camera.toml")
        t0 = time.perf_counter()
        calibration = calibrate_mock_cell(
            out_dir / "camera.toml", out_dir / "calibration.mcap",
            MockCalibration(board=options.board, views=options.calibration_views,
                            corner_views=options.corner_views, robot=options.robot,
                            profile=options.profile, seed=options.seed))
        write_text_atomic(out_dir / "calibration.json", json.dumps(
            {**calibration.report, "mount_file": str(out_dir / "camera.toml")},
            indent=1) + "\n")
        timings["calibrate"] = time.perf_counter() - t0
        mount = calibration.mount
    else:
        mount = options.mount or bundled
    kinematics, arm_report = _capture(out_dir, options, settings, mount, step, timings)

    step("checking the recording")
    recording = Recording.open(out_dir / "demo.mcap")
    check = summarize(recording)
    pair = recording[0]

    step(f"rectifying and matching ({options.method}; the first run compiles the matcher, "
         "later runs reuse the cache)")
    warmup.wait(compiling)
    photometric = for_recording(options.photometric, recording.metadata)
    recon = reconstruct_pair(pair, stereo=options.matcher(), photometric=photometric)
    timings.update({k: recon.timings_s[k] for k in ("decode", "photometric", "rectify",
                                                    "match", "triangulate")})

    step("writing the point cloud and images")
    t0 = time.perf_counter()
    _write_products(recon, out_dir)
    timings["write"] = time.perf_counter() - t0

    step("scoring against the mock camera's ground truth")
    t0 = time.perf_counter()
    accuracy = score_reconstruction(recon.depth_original, pair, swapped=recon.swapped)
    point_error = point_error_mm(recon.points_base, recording.metadata)
    timings["score"] = time.perf_counter() - t0

    step("finding the table and the objects on it")
    t0 = time.perf_counter()
    truth = SceneTruth.from_json(recording.metadata["scene_truth"])
    analysis, scene_score = analyze_points(recon.points_base, recon.colors_bgr,
                                           out_dir / "scene", source="armstereo demo",
                                           truth=truth)
    timings["scene"] = time.perf_counter() - t0
    before = None
    if calibration is not None and options.compare:
        t0 = time.perf_counter()
        before = _before(pair, bundled, recording.metadata, truth, options)
        timings["before"] = time.perf_counter() - t0
    timings["total"] = time.perf_counter() - t_start
    report = _report(recon, accuracy, timings, options)
    report["scene"] = {"objects": analysis.as_dict()["objects"],
                       "score": scene_score.as_dict()}
    report.update(profile=options.profile_name, cell=recording.metadata.get("mock_cell", ""),
                  point_error_mm=point_error, photometric=recon.photometric,
                  mount={"name": mount.name, "file": "camera.toml" if calibration else
                         ("bundled" if options.mount is None else "given")},
                  calibration=_calibration_report(calibration),
                  before=before,
                  kinematics=_kinematics_report(kinematics, arm_report),
                  check={"fk_vs_controller_max_mm": check["fk_vs_controller_max_mm"],
                         "warnings": check["warnings"]},
                  error_budget={"sources": _sources(options),
                                "median_abs_rel_depth_error":
                                    accuracy.median_abs_rel_depth_error,
                                "median_point_error_mm": point_error["median"],
                                "table": ERROR_BUDGET_TABLE})
    write_text_atomic(out_dir / "report.json", json.dumps(report, indent=2) + "\n")
    return report


class _Steps:
    """Numbered progress lines: ``[k/n] text``."""

    def __init__(self, n: int, progress: Callable[[str], None]):
        self.n, self.k, self.progress = n, 0, progress

    def __call__(self, text: str) -> None:
        self.k += 1
        self.progress(f"[{self.k}/{self.n}] {text}")


def _capture(out_dir: Path, options: DemoOptions, settings: CaptureSettings,
             mount: CameraMount, step, timings: dict[str, float]):
    """Capture the pair with the software believing ``mount``; (kinematics, arm) for the
    report."""
    t0 = time.perf_counter()
    given = load_arm_model(options.robot, mount=CameraMount.load(None))
    noise = options.camera_noise
    if noise is None:
        noise = 1.0 if options.profile_name == "ideal" else 0.0
    arm_config = backends.arm_config("mock", joint_noise=options.joint_noise, seed=options.seed,
                                     profile=options.profile)
    camera_config = backends.camera_config("mock", noise=noise, seed=options.seed,
                                           profile=options.profile)
    with backends.build_arm("mock", arm_config, given) as arm:
        kinematics = _kinematics(given, arm, options, mount)
        model = kinematics.model
        step(f"capturing a pair (baseline {options.baseline * 1000:.0f} mm) with "
             f"{kinematics.source} kinematics and the {mount.name} mount")
        plan = plan_capture(model, arm.joint_positions(), settings)
        with backends.build_camera("mock", camera_config, model, arm) as camera:
            capture_to_file(arm, camera, model, plan, out_dir / "demo.mcap",
                            {**model_metadata(model), **kinematics.metadata(), "arm": "mock",
                             "camera": "mock", "baseline_m": repr(options.baseline),
                             "direction": "x", "pairs": "1", "source": "armstereo demo",
                             "mock_profile": options.profile_name},
                            progress=None)
    timings["capture"] = time.perf_counter() - t0
    return kinematics, arm


def _precheck(options: DemoOptions, settings: CaptureSettings, mount: CameraMount) -> None:
    """The capture's pre-flight checks with the bundled mount (the calibrated one differs by
    millimetres), before anything is calibrated or written; PreflightError if they fail."""
    given = load_arm_model(options.robot, mount=mount)
    config = backends.arm_config("mock", joint_noise=options.joint_noise, seed=options.seed,
                                 profile=options.profile)
    with backends.build_arm("mock", config, given) as arm:
        model = _kinematics(given, arm, options, mount).model
        plan_capture(model, arm.joint_positions(), settings).require_ok()


def _before(pair, bundled: CameraMount, metadata: dict[str, str], truth: SceneTruth,
            options: DemoOptions) -> dict:
    """The same pair reconstructed with the bundled mount file (what skipping the
    calibration gives): the images as recorded, the camera as the bundled file says."""
    photometric = as_options(options.photometric).with_model(bundled.vignetting)
    recon = reconstruct_pair(remounted(pair, bundled), stereo=options.matcher(),
                             photometric=photometric)
    return {"mount": bundled.name, **compare_mount(recon, pair, metadata, truth)}


def _calibration_report(cal) -> dict | None:
    """The calibration's headline figures for the demo report (the whole report is
    calibration.json)."""
    if cal is None:
        return None
    rep = cal.report
    quality = rep.get("quality", {})
    return {"mount_file": "camera.toml", "recording": "calibration.mcap",
            "report": "calibration.json", "views_used": len(rep["views"]["used"]),
            "rms_px": rep["refined"]["rms_px"],
            "predicted_error": quality.get("predicted_error"),
            "truth_error": rep.get("truth_error"),
            "board_shape": rep["refined"].get("board_shape"),
            "vignetting": rep.get("vignetting"), "warnings": rep["warnings"]}


ERROR_BUDGET_TABLE = "bench/results/error_budget.md"


def _kinematics(given: ArmModel, arm, options: DemoOptions,
                mount: CameraMount) -> CaptureKinematics:
    """The kinematics the capture uses: the arm's broadcast table (read like a UR's), or the
    model given when ``read_calibration`` is off; then the software's ``mount``."""
    chosen = (choose_kinematics(given, arm, live=False) if options.read_calibration
              else CaptureKinematics(given, "nominal"))
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
    if p.residual.any:
        out.append("arm pose residual")
    return out


def _write_products(recon, out_dir: Path) -> None:
    names = {"ply": "points.ply", "disparity": "disparity.png", "rectified": "rectified.png",
             "depth_error": "depth_error.png", "mcap": "reconstruction.mcap"}
    write_outputs(recon, out_dir, "demo", paths={k: out_dir / v for k, v in names.items()},
                  metadata={"photometric": record_json(recon.photometric)})


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
