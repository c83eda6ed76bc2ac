"""``armstereo sweep``: the TASER baseline experiment, on the mock or on a real arm."""

from __future__ import annotations

import argparse
import logging
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from armstereo import backends
from armstereo.apps.sweep import (
    SCENE_MIN_DENSITY,
    SceneMeasurement,
    Target,
    best_baseline,
    best_scene_baseline,
    format_scene_table,
    format_table,
    plot,
    plot_scene,
    run_sweep,
    write_csv,
    write_scene_csv,
)
from armstereo.capture import CaptureSettings, plan_capture
from armstereo.capture.plan import MAX_BASELINE_M
from armstereo.capture.run import model_metadata
from armstereo.capture.session import capture_to_file, confirm_live_motion
from armstereo.cli import args as args_
from armstereo.cli.backend_flags import BackendChoice, add_backend_flags, backend_choice
from armstereo.cli.capture_cmd import add_motion_flags, ask_to_move
from armstereo.devices import MotionLimits
from armstereo.errors import ConfigError
from armstereo.io.files import output_folder
from armstereo.mount import CameraMount
from armstereo.reconstruct.pipeline import reconstruct_pair
from armstereo.recording import Recording
from armstereo.robot.arm_model import ArmModel
from armstereo.robot.model_file import load_arm_model
from armstereo.robot.source import choose_kinematics

log = logging.getLogger("armstereo.sweep")

DEFAULT_BASELINES = "0.025,0.05,0.075,0.1,0.15,0.2,0.3"
DEFAULT_DISTANCES = "0.8,1.1,1.4,1.7,2.0,2.2"
MAX_TARGET_DISTANCE_M = 20.0  # farther than any table-top stereo pair resolves
# A real sensor is never noise free; the sweep's shape depends on it.
SWEEP_DEFAULTS = {"noise": 2.0}


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("sweep", help="measure planar targets with several baselines",
                       description="Reproduce the TASER experiment: planar targets at known "
                       "distances, one capture per baseline, measured against the truth.")
    p.add_argument("--baselines", default=None, type=args_.positive_list("m", cap=MAX_BASELINE_M),
                   help=f"comma-separated baselines in m (default {DEFAULT_BASELINES})")
    p.add_argument("--distances", default=None,
                   type=args_.positive_list("m", cap=MAX_TARGET_DISTANCE_M),
                   help="mock only: target distances in m (default " + DEFAULT_DISTANCES + ")")
    p.add_argument("--target", action="append", default=[], metavar="U0,V0,U1,V1=DIST",
                   help="real arm: a target's pixel box in the first view and its measured "
                   "distance (m); repeat for each target")
    p.add_argument("--out", default=None, help="output folder (default ./armstereo-sweep-<time>)")
    p.add_argument("--method", choices=["birchfield", "sgbm"], default="birchfield")
    add_motion_flags(p)
    p.add_argument("--yes", action="store_true", help="allow live motion without asking")
    add_backend_flags(p, defaults=SWEEP_DEFAULTS)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    baselines = args.baselines or _floats(DEFAULT_BASELINES)
    mock = args.arm == "mock"
    if not mock and not args.target:
        raise ConfigError("a sweep on a real arm needs --target U0,V0,U1,V1=DIST for each "
                          "target you placed and measured")
    if mock and args.target:
        raise ConfigError("--target is for a real arm; the mock places its own targets "
                          "(--distances)")
    if not mock and args.distances is not None:
        raise ConfigError("--distances is for the mock arm; on a real arm give --target")
    fixed = {"arm": {"layout": "horizontal"}} if mock else {}
    choice = backend_choice(args, defaults=SWEEP_DEFAULTS, fixed=fixed)
    out = Path(args.out or f"armstereo-sweep-{time.strftime('%Y%m%d-%H%M%S')}")
    if mock and choice.arm_config.profile.scene == "desk":
        return _desk_sweep(args, choice, baselines, out)
    model = load_arm_model(args.robot, mount=CameraMount.load(args.mount))
    capture_one = (_mock_capture(args, choice, model, baselines, out) if mock
                   else _live_capture(args, choice, model, out))
    with output_folder(out):  # a sweep that fails before its first capture leaves nothing
        results = run_sweep(baselines, capture_one, lambda s: log.info("%s", s))
        write_csv(out / "sweep.csv", results)
        plot(out / "sweep.png", results,
             f"armstereo sweep ({args.arm} {model.name}, {args.method})")
    print("\n".join(format_table(results)))
    best = best_baseline(results)
    span = f"{min(m.true_distance_m for m in results):g}-" \
           f"{max(m.true_distance_m for m in results):g} m"
    print(f"best baseline for {span}: " + (f"{best * 100:g} cm" if best is not None else
                                           "none measured every target"))
    print(f"files: {out}/sweep.csv {out}/sweep.png and one recording per baseline")
    return 0


def _desk_sweep(args, choice: BackendChoice, baselines: list[float], out: Path) -> int:
    """The realistic profile's sweep: the demo's desk capture once per baseline, scored over
    every pixel both views see (see armstereo.apps.sweep)."""
    from armstereo.apps.demo import DemoOptions, demo_settings, run_demo

    if args.distances is not None:
        raise ConfigError("--distances places planar targets (ideal profile); the realistic "
                          "profile sweeps the desk scene at the demo's height")
    for b in baselines:  # every baseline's pre-flight check before anything is calibrated
        demo_settings(DemoOptions(robot=args.robot, baseline=b))
    results = []
    with output_folder(out):  # a sweep that fails before its first capture leaves nothing
        mount = _sweep_mount(args, choice, out)
        for i, b in enumerate(baselines, 1):
            log.info("[%d/%d] baseline %g cm", i, len(baselines), b * 100)
            options = DemoOptions(robot=args.robot, baseline=b, method=args.method,
                                  seed=choice.arm_config.seed, profile=choice.arm_config.profile,
                                  mount=mount, calibrate=False, compare=False)
            folder = out / f"baseline_{b * 1000:.0f}mm"
            folder.mkdir(exist_ok=True)
            report = run_demo(folder, options)
            acc = report["accuracy"]
            results.append(SceneMeasurement(b, acc["median_abs_rel_depth_error"],
                                            acc["within_1pct"], acc["density"],
                                            report["point_error_mm"]["median"]))
        write_scene_csv(out / "sweep.csv", results)
        plot_scene(out / "sweep.png", results, f"armstereo sweep (desk, {args.robot}, "
                   f"{choice.arm_config.profile.name} profile, {args.method})")
    print("\n".join(format_scene_table(results)))
    best = best_scene_baseline(results)
    print("best baseline for the desk at 0.55 m: " + (
        f"{best * 100:g} cm" if best is not None
        else f"none kept {SCENE_MIN_DENSITY:.0%} density"))
    print(f"files: {out}/sweep.csv {out}/sweep.png and one demo folder per baseline")
    return 0


def _sweep_mount(args, choice: BackendChoice, out: Path) -> CameraMount:
    """The desk sweep's camera: ``--mount``, or the cell's camera calibrated once (the mount
    file ``camera.toml`` in the sweep folder, as ``armstereo calibrate`` writes it)."""
    if args.mount is not None:
        return CameraMount.load(args.mount)
    from armstereo.apps.calibrate import MockCalibration, calibrate_mock_cell

    log.info("calibrating the camera on the cell (%s profile, seed %d) -> camera.toml",
             choice.arm_config.profile.name, choice.arm_config.seed)
    return calibrate_mock_cell(out / "camera.toml", out / "calibration.mcap", MockCalibration(
        robot=args.robot, profile=choice.arm_config.profile, seed=choice.arm_config.seed)).mount


def _floats(text: str) -> list[float]:
    return [float(v) for v in text.split(",")]


def _settings(args: argparse.Namespace, b: float) -> CaptureSettings:
    return CaptureSettings(baseline=b, direction=np.array([1.0, 0.0, 0.0]), pairs=1,
                           settle_s=args.settle,
                           limits=MotionLimits(linear_speed=args.speed,
                                               linear_acceleration=args.acceleration))


def _reconstruct(path: Path, args, near: float, far: float):
    return reconstruct_pair(Recording.open(path)[0], method=args.method, near=near, far=far)


def _mock_capture(args, choice: BackendChoice, model: ArmModel, baselines: list[float],
                  out: Path):
    distances = args.distances or _floats(DEFAULT_DISTANCES)
    q0 = backends.mock_start_joints(model, "horizontal")
    seed = choice.camera_config.seed
    ts = backends.mock_target_scene(distances, model.camera_pose(q0), model.mount.intrinsics,
                                    max_baseline=max(baselines), seed=seed)
    targets = [Target(t.distance, t.pixel_box) for t in ts.targets]
    near, far = 0.85 * min(distances), 1.15 * max(distances)
    camera_config = replace(choice.camera_config, scene=ts.scene)

    def capture_one(b: float):
        path = out / f"sweep_b{b * 1000:.0f}mm.mcap"
        with backends.build_arm("mock", choice.arm_config, model) as arm:
            plan = plan_capture(model, arm.joint_positions(), _settings(args, b))
            plan.require_ok()
            with backends.build_camera("mock", camera_config, model, arm) as cam:
                capture_to_file(arm, cam, model, plan, path, _meta(args, model, b),
                                progress=None)
        recon = _reconstruct(path, args, near, far)
        return recon.depth_original, targets, recon.depth_truth

    return capture_one


def _live_capture(args, choice: BackendChoice, model: ArmModel, out: Path):
    targets = [Target.parse(t) for t in args.target]
    near = 0.85 * min(t.distance for t in targets)
    far = 1.15 * max(t.distance for t in targets)
    confirmed = False

    def capture_one(b: float):
        nonlocal confirmed
        path = out / f"sweep_b{b * 1000:.0f}mm.mcap"
        with backends.build_arm(choice.arm, choice.arm_config, model) as arm:
            arm.require_ok()
            kinematics = choose_kinematics(model, arm, live=True)
            plan = plan_capture(kinematics.model, arm.joint_positions(), _settings(args, b))
            plan.require_ok()
            if not confirmed:
                confirm_live_motion(live=True, yes=args.yes,
                                    ask=lambda: ask_to_move(f"The {args.robot} "))
                confirmed = True
            m = kinematics.model
            with backends.build_camera(choice.camera, choice.camera_config, m, arm) as cam:
                capture_to_file(arm, cam, m, plan, path,
                                {**_meta(args, m, b), **kinematics.metadata()}, progress=None)
        recon = _reconstruct(path, args, near, far)
        return recon.depth_original, targets, None

    return capture_one


def _meta(args, model: ArmModel, b: float) -> dict[str, str]:
    return {**model_metadata(model), "arm": args.arm, "camera": args.camera,
            "baseline_m": repr(b), "direction": "x", "pairs": "1", "source": "armstereo sweep"}
