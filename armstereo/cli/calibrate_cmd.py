"""``armstereo calibrate``: camera intrinsics and hand-eye transform from views of a board.

Live: grab the start image, find the board, plan ``--views`` diverse views, check every move as
capture does (``--dry-run`` stops there), move, settle, grab and record each view into an MCAP
calibration recording, then calibrate and write the mount file. ``--from CALIB.mcap`` redoes
the computation on a recorded session without moving anything. ``--images GLOB --poses FILE``
calibrates images and arm poses recorded elsewhere (it writes a calibration recording of them
first, so ``--from`` works on it). See docs/calibration.md.
"""

from __future__ import annotations

import argparse
import json
import logging
from pathlib import Path

from armstereo import backends
from armstereo.apps.calibrate import (
    calibration_options,
    finish,
    mock_camera_values,
    plan_session,
)
from armstereo.calibration.board import Board, parse_board
from armstereo.calibration.calibrate import Calibration
from armstereo.calibration.checks import MIN_VIEWS
from armstereo.calibration.report import report_lines
from armstereo.calibration.session import calibrate_recording, calibration_metadata
from armstereo.calibration.views import MAX_VIEWS, ViewPlanSettings
from armstereo.capture.plan import CaptureSettings, Workspace
from armstereo.capture.run import model_metadata
from armstereo.capture.session import capture_to_file, confirm_live_motion
from armstereo.capture.view_tour import tour_settings
from armstereo.cli import args as args_
from armstereo.cli.backend_flags import BackendChoice, add_backend_flags, backend_choice
from armstereo.cli.calibrate_import_cmd import add_import_flags, import_requested, run_import
from armstereo.cli.capture_cmd import add_motion_flags, ask_to_move
from armstereo.devices import MotionLimits
from armstereo.errors import ArmstereoError, ConfigError
from armstereo.io.files import write_text_atomic
from armstereo.mount import CameraMount
from armstereo.robot.model_file import load_arm_model
from armstereo.robot.source import choose_kinematics

log = logging.getLogger("armstereo.calibrate")

DEFAULT_VIEWS = 15
DEFAULT_CORNERS = 4
DEFAULT_ROBOT = "ur5e"
# Flags that only a live session takes (refused with --from, which moves nothing).
LIVE_ONLY = ("arm", "camera", "mount", "dry_run", "yes", "recording", "workspace")


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("calibrate", help="camera intrinsics and hand-eye transform from views "
                       "of a calibration board", description=__doc__.split("\n\n")[1])
    add_backend_flags(p)
    p.set_defaults(arm=None, camera=None, robot=None)  # to tell given flags from defaults
    p.add_argument("--board", type=parse_board_arg, default=None,
                   help="chessboard:COLSxROWS:SQUARE_M or charuco:COLSxROWS:SQUARE_M:MARKER_M"
                   "[:DICT] (squares, metres); required unless --from")
    p.add_argument("--views", type=args_.whole(MIN_VIEWS, MAX_VIEWS), default=DEFAULT_VIEWS,
                   help=f"views to record, the start view included (default {DEFAULT_VIEWS})")
    p.add_argument("--corner-views", type=args_.whole(0, MAX_VIEWS), default=DEFAULT_CORNERS,
                   help=f"of the --views, how many put the board into an image corner (for "
                   f"the lens's distortion and vignetting there; default {DEFAULT_CORNERS})")
    p.add_argument("--out", required=True, help="mount file to write (.toml)")
    p.add_argument("--recording", default=None,
                   help="calibration recording to write (default: --out with .mcap)")
    p.add_argument("--from", dest="from_recording", type=args_.input_file, default=None,
                   metavar="CALIB.mcap", help="redo the computation on a recorded session "
                   "(moves nothing)")
    p.add_argument("--json", action="store_true", help="print the whole report as JSON")
    p.add_argument("--force", action="store_true", help="overwrite --out and the recording")
    p.add_argument("--dry-run", action="store_true",
                   help="grab one image, plan and check the views, move nothing")
    p.add_argument("--yes", action="store_true", help="allow live motion without asking")
    add_motion_flags(p)
    p.add_argument("--max-tilt", type=args_.positive("deg", cap=60.0), default=35.0,
                   help="tilt of the optical axis about the board centre (deg, default 35)")
    p.add_argument("--max-roll", type=args_.non_negative("deg", cap=90.0), default=60.0,
                   help="roll about the optical axis (deg, default 60)")
    p.add_argument("--workspace", default=None,
                   help="base-frame box xmin,xmax,ymin,ymax,zmin,zmax (m) the moves must stay in")
    add_import_flags(p)
    p.set_defaults(func=run)


def parse_board_arg(text: str) -> Board:
    """``--board`` for argparse: a bad spec is one line naming the flag, exit 2."""
    try:
        return parse_board(text)
    except ArmstereoError as err:
        raise argparse.ArgumentTypeError(str(err).removeprefix(f"--board {text!r}: ")) from None


def run(args: argparse.Namespace) -> int:
    if import_requested(args):
        return run_import(args, _output_path, _print_result)
    if args.from_recording is not None:
        return _run_offline(args)
    return _run_live(args)


def _run_offline(args: argparse.Namespace) -> int:
    given = [f"--{name.replace('_', '-')}" for name in LIVE_ONLY
             if getattr(args, name) not in (None, False)]
    if given:
        raise ConfigError(f"--from recomputes a recorded session and moves nothing; "
                          f"{', '.join(given)} do(es) not apply")
    out = _output_path(args.out, "--out", args.force, dry_run=False)
    cal = calibrate_recording(args.from_recording, board=args.board, robot=args.robot,
                              options=calibration_options(out))
    write_text_atomic(out, cal.mount_toml)
    _print_result(args, cal, out, args.from_recording)
    return 0


def _run_live(args: argparse.Namespace) -> int:
    if args.board is None:
        raise ConfigError("--board is required (or --from CALIB.mcap to recompute a recording)")
    args.arm = "mock" if args.arm is None else args.arm
    args.camera = "mock" if args.camera is None else args.camera
    out = _output_path(args.out, "--out", args.force, args.dry_run)
    recording = _output_path(args.recording or str(Path(args.out).with_suffix(".mcap")),
                             "--recording", args.force, args.dry_run)
    if recording.resolve() == out.resolve():
        raise ConfigError(f"--recording and --out are the same file ({out})")
    mount = CameraMount.load(args.mount)
    model = load_arm_model(args.robot or DEFAULT_ROBOT, mount=mount)
    choice = _backends(args, mount)
    arm = backends.build_arm(choice.arm, choice.arm_config, model)
    with arm:
        arm.require_ok()
        kinematics = choose_kinematics(model, arm, live=choice.arm != "mock")
        model = kinematics.model  # plans the views and computes every pose with the arm's table
        camera = backends.build_camera(choice.camera, choice.camera_config, model, arm)
        with camera:
            plan = plan_session(model, camera, arm.joint_positions(), args.board,
                                views=_view_settings(args), tour=_tour_settings(args),
                                corner_views=args.corner_views)
            if args.dry_run or not plan.ok:
                print("\n".join(plan.describe()))
            plan.tour.require_ok()
            if args.dry_run:
                print("dry run: nothing moved")
                return 0
            host = getattr(choice.arm_config, "host", None)
            confirm_live_motion(live=choice.arm != "mock", yes=args.yes,
                                ask=lambda: ask_to_move(f"The {model.name} at {host} "))
            metadata = {**model_metadata(model), **kinematics.metadata(),
                        **_metadata(args, choice),
                        **calibration_metadata(args.board, args.views)}
            result = capture_to_file(arm, camera, model, plan.tour, recording, metadata)
    log.info("recorded %d views -> %s; calibrating", result.views, recording)
    cal = finish(recording, out, args.board)
    _print_result(args, cal, out, recording)
    return 0


def _backends(args: argparse.Namespace, mount: CameraMount) -> BackendChoice:
    """The backends, with the mock camera set up for a calibration (board on the table, a true
    camera that differs from the mount file)."""
    choice = backend_choice(args)
    if args.camera != "mock":
        return choice
    seed = choice.camera_config.seed
    return backend_choice(args, fixed={"camera": mock_camera_values(args.board, mount, seed)})


def _view_settings(args: argparse.Namespace) -> ViewPlanSettings:
    return ViewPlanSettings(n_views=args.views, max_tilt_deg=args.max_tilt,
                            max_roll_deg=args.max_roll)


def _tour_settings(args: argparse.Namespace) -> CaptureSettings:
    limits = MotionLimits(linear_speed=args.speed, linear_acceleration=args.acceleration)
    box = Workspace.parse(args.workspace) if args.workspace else None
    return tour_settings(settle_s=args.settle, limits=limits, workspace=box)


def _output_path(text: str, flag: str, force: bool, dry_run: bool) -> Path:
    path = Path(text)
    if not text.strip():
        raise ConfigError(f"{flag} is empty")
    if path.is_dir():
        raise ConfigError(f"{flag} {path} is a directory; give a file name")
    if path.exists() and not force and not dry_run:
        raise ConfigError(f"{flag} {path} exists; pass --force to overwrite it")
    if not path.parent.exists():
        raise ConfigError(f"{flag} directory {path.parent} does not exist")
    return path


def _metadata(args: argparse.Namespace, choice: BackendChoice) -> dict[str, str]:
    arm, cam = choice.arm_config, choice.camera_config
    return {
        "arm": args.arm, "host": getattr(arm, "host", None) or "", "camera": args.camera,
        "speed_m_s": repr(args.speed), "acceleration_m_s2": repr(args.acceleration),
        "settle_s": repr(args.settle), "camera_noise": repr(getattr(cam, "noise", 0.0)),
        "mock_profile": getattr(getattr(arm, "profile", None), "name", "")
        or getattr(getattr(cam, "profile", None), "name", ""),
    }


def _print_result(args: argparse.Namespace, cal: Calibration, out: Path,
                  recording: Path) -> None:
    report = {**cal.report, "mount_file": str(out)}
    if args.json:
        print(json.dumps(report, indent=1))
        return
    print("\n".join(report_lines(report)))
    if "truth_error" in report:
        e = report["truth_error"]
        vig = e.get("vignetting_corner_rel")
        print(f"against the mock's truth: {e['translation_m'] * 1000:.3f} mm, "
              f"{e['rotation_deg']:.4f} deg, focal {e['focal_rel'] * 100:+.3f} %"
              + ("" if vig is None else f", vignetting at the corners {vig * 100:+.2f} %"))
    print(f"mount -> {out} (recording {recording})")
