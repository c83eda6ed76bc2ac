"""``armstereo demo --scan``: calibrate the mock cell's camera, scan the scene from several
viewpoints, fuse the pairs and score the model.

The workflow of the pair demo (:mod:`armstereo.apps.demo`) with a scan: the camera is
calibrated on the cell (:func:`armstereo.apps.calibrate.calibrate_mock_cell`, the mount file
``camera.toml``), the scan is recorded with that mount by
:func:`armstereo.apps.scan.record_scan` (what ``armstereo scan`` runs), fused by
:func:`armstereo.fusion.run.fuse_recording` (what ``armstereo fuse`` runs, photometric
correction from the mount file's vignetting) and scored against the mock scene's exact
geometry; a picture of the mesh is rendered headless. The same scan fused with the bundled
mount file (``fused_bundled/``) gives the "before" figures. The default is the ``realistic``
profile (the desk); ``ideal`` is the exact mock with 1 grey level of sensor noise. Numbers:
docs/scan.md and docs/error-budget.md.
"""

from __future__ import annotations

import json
import time
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import cv2

from armstereo import __version__, backends
from armstereo.apps.calibrate import MockCalibration, calibrate_mock_cell
from armstereo.apps.scan import ScanRequest, backend_metadata, record_scan
from armstereo.capture.scan_plan import parse_views
from armstereo.errors import ConfigError
from armstereo.fusion.mesh_ply import read_mesh_ply
from armstereo.fusion.render import mesh_picture
from armstereo.fusion.run import FusionOptions, fuse_recording
from armstereo.io.files import write_text_atomic
from armstereo.mount import CameraMount
from armstereo.reconstruct import warmup
from armstereo.robot.model_file import load_arm_model

TARGET_M = (-0.45, -0.13, 0.03)  # the mock table scene's centre, 3 cm above the table
SCAN_DEMO_FILES = ("scan.mcap", "fused", "mesh.png", "report.json", "camera.toml",
                   "calibration.mcap", "calibration.json", "fused_bundled")
# The targets for a fused mock scan with camera noise.
TARGET_ACCURACY_MM = 1.0
TARGET_COMPLETENESS_5MM = 0.95


@dataclass(frozen=True)
class ScanDemoOptions:
    """The scan (layout, geometry in m and deg, seed) and the fusion (voxel m, matcher)."""

    views: str = "ring:12"
    radius: float = 0.45
    elevation_deg: float = 55.0
    baseline: float = 0.06
    voxel: float = 0.002
    method: str = "birchfield"
    profile: str = "realistic"
    camera_noise: float | None = None  # None: 1.0 on the ideal profile, 0 otherwise
    seed: int = 0
    robot: str = "ur5e"
    calibrate: bool = True  # calibrate the cell's camera first (else: the bundled mount)
    calibration_views: int = 10
    corner_views: int = 4
    photometric: Any = True  # armstereo.photometric: True, False or PhotometricOptions
    compare: bool = True  # also fuse with the bundled mount file (the "before" figures)

    def check(self) -> None:
        """ConfigError for an option out of range (before a folder is made)."""
        from armstereo.fusion.nbv import parse_auto

        if parse_auto(self.views) is None:
            parse_views(self.views)
        if not 0 < self.voxel <= 0.1:
            raise ConfigError(f"--voxel must be in (0, 0.1] m, got {self.voxel}")


def run_scan_demo(out_dir: Path, options: ScanDemoOptions = ScanDemoOptions(),
                  progress: Callable[[str], None] = lambda s: None) -> dict:
    """Scan, fuse, render and score into ``out_dir``; returns the report (also report.json)."""
    options.check()
    compiling = warmup.start(options.method)  # compiles on the other core while we scan
    try:
        return _run(Path(out_dir), options, progress, compiling)
    finally:
        warmup.wait(compiling)


def _run(out_dir: Path, options: ScanDemoOptions, progress, compiling) -> dict:
    timings: dict[str, float] = {}
    t_all = time.perf_counter()
    noise = options.camera_noise
    if noise is None:
        noise = 1.0 if options.profile == "ideal" else 0.0
    n = 4 if options.calibrate else 3
    bundled = CameraMount.load(None)
    mount, calibration = bundled, None
    if options.calibrate:
        progress(f"[1/{n}] calibrating the camera: {options.calibration_views} views -> "
                 "camera.toml")
        t0 = time.perf_counter()
        calibration = calibrate_mock_cell(
            out_dir / "camera.toml", out_dir / "calibration.mcap",
            MockCalibration(views=options.calibration_views, corner_views=options.corner_views,
                            robot=options.robot, profile=options.profile, seed=options.seed))
        write_text_atomic(out_dir / "calibration.json", json.dumps(
            {**calibration.report, "mount_file": str(out_dir / "camera.toml")},
            indent=1) + "\n")
        mount = calibration.mount
        timings["calibrate"] = time.perf_counter() - t0
    k = n - 2
    progress(f"[{k}/{n}] scanning the mock scene from {options.views} viewpoints "
             f"({options.profile} profile, baseline {options.baseline * 1000:.0f} mm)")
    t0 = time.perf_counter()
    model = load_arm_model(options.robot, mount=mount)
    arm = backends.arm_config("mock", seed=options.seed, profile=options.profile)
    camera = backends.camera_config("mock", noise=noise, seed=options.seed,
                                    profile=options.profile)
    request = ScanRequest(target=TARGET_M, views=options.views, radius=options.radius,
                          elevation_deg=options.elevation_deg, baseline=options.baseline)
    outcome = record_scan(out_dir / "scan.mcap", request, model, arm_config=arm,
                          camera_config=camera,
                          metadata={**backend_metadata("mock", arm, "mock", camera),
                                    "source": "armstereo demo --scan"}, progress=None)
    timings["scan"] = time.perf_counter() - t0

    progress(f"[{k + 1}/{n}] fusing {len(outcome.result.pairs)} pairs at "
             f"{options.voxel * 1000:g} mm ({options.method}; the first run compiles the "
             "matcher)")
    t0 = time.perf_counter()
    warmup.wait(compiling)
    fusion_options = FusionOptions(voxel=options.voxel, method=options.method,
                                   photometric=options.photometric)
    fusion = fuse_recording(out_dir / "scan.mcap", out_dir / "fused", fusion_options)
    timings["fuse"] = time.perf_counter() - t0
    before = None
    if calibration is not None and options.compare:
        t0 = time.perf_counter()
        before = fuse_recording(out_dir / "scan.mcap", out_dir / "fused_bundled",
                                replace(fusion_options, mount=bundled))
        timings["fuse_bundled"] = time.perf_counter() - t0

    progress(f"[{n}/{n}] rendering the mesh")
    t0 = time.perf_counter()
    picture = mesh_picture(read_mesh_ply(out_dir / "fused" / "mesh.ply"))
    if not cv2.imwrite(str(out_dir / "mesh.png"), picture):
        raise ConfigError(f"could not write {out_dir / 'mesh.png'}")
    timings["render"] = time.perf_counter() - t0
    timings["total"] = time.perf_counter() - t_all
    report = _report(options, noise, outcome, fusion, timings)
    report.update(cell=f"{outcome_profile(options)} seed {options.seed}",
                  mount={"name": mount.name,
                         "file": "camera.toml" if calibration else "bundled"},
                  calibration=_calibration_summary(calibration),
                  photometric=fusion.get("photometric"),
                  before=None if before is None else {
                      "mount": bundled.name, "accuracy": before.get("accuracy"),
                      "fused_points": before["fused_points"]})
    write_text_atomic(out_dir / "report.json", json.dumps(report, indent=2) + "\n")
    return report


def outcome_profile(options: ScanDemoOptions) -> str:
    return getattr(options.profile, "name", options.profile)


def _calibration_summary(cal) -> dict | None:
    if cal is None:
        return None
    rep = cal.report
    return {"mount_file": "camera.toml", "recording": "calibration.mcap",
            "report": "calibration.json", "views_used": len(rep["views"]["used"]),
            "rms_px": rep["refined"]["rms_px"],
            "predicted_error": rep.get("quality", {}).get("predicted_error"),
            "truth_error": rep.get("truth_error"), "vignetting": rep.get("vignetting")}


def _report(options: ScanDemoOptions, noise: float, outcome, fusion: dict,
            timings: dict[str, float]) -> dict:
    scan = outcome.tour.scan
    acc = fusion.get("accuracy")
    targets = None
    if acc is not None:
        targets = {"accuracy_mean_mm": TARGET_ACCURACY_MM,
                   "completeness_within_5mm": TARGET_COMPLETENESS_5MM,
                   "met": bool(acc["accuracy_mean_mm"] <= TARGET_ACCURACY_MM
                               and acc["completeness_within_5mm"] >= TARGET_COMPLETENESS_5MM
                               and acc["accuracy_mean_mm"]
                               < acc["raw_pairs"]["accuracy_mean_mm"])}
    return {
        "profile": options.profile, "camera_noise": noise, "views": options.views,
        "viewpoints_kept": len(scan.views), "viewpoints_dropped": len(scan.dropped),
        "pairs": len(outcome.result.pairs), "baseline_m": options.baseline,
        "radius_m": options.radius, "elevation_deg": options.elevation_deg,
        "voxel_m": options.voxel, "method": options.method, "matcher": fusion["matcher"],
        "timings_s": {**({"calibrate": round(timings["calibrate"], 3)}
                         if "calibrate" in timings else {}),
                      "scan": round(timings["scan"], 3),
                      **{f"fuse_{k}": v for k, v in fusion["timings_s"].items()},
                      **({"fuse_bundled": round(timings["fuse_bundled"], 3)}
                         if "fuse_bundled" in timings else {}),
                      "render": round(timings["render"], 3),
                      "total": round(timings["total"], 3)},
        "accuracy": acc, "targets": targets,
        "mesh": fusion["mesh"], "fused_points": fusion["fused_points"],
        "voxels": fusion["voxels"], "memory_mb": fusion["memory_mb"],
        "armstereo_version": __version__,
    }
