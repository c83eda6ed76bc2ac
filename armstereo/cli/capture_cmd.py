"""``armstereo capture``: stop-and-shoot capture of stereo pairs into an MCAP recording."""

from __future__ import annotations

import argparse
import logging
import sys
from pathlib import Path

from armstereo import backends
from armstereo.capture import CaptureSettings, Workspace, plan_capture
from armstereo.capture.plan import MAX_BASELINE_M, MAX_PAIRS, MAX_SETTLE_S, parse_direction
from armstereo.capture.run import CaptureResult, model_metadata
from armstereo.capture.session import capture_to_file, confirm_live_motion
from armstereo.cli import args as args_
from armstereo.cli.backend_flags import BackendChoice, add_backend_flags, backend_choice
from armstereo.devices import MAX_LINEAR_ACCELERATION, MAX_LINEAR_SPEED, MotionLimits
from armstereo.errors import ConfigError
from armstereo.mount import CameraMount
from armstereo.robot.arm_model import ArmModel
from armstereo.robot.model_file import load_arm_model
from armstereo.robot.source import choose_kinematics

log = logging.getLogger("armstereo.capture")


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("capture", help="move the camera by a baseline and record stereo pairs",
                       description="Stop-and-shoot capture: at each view wait until steady, "
                       "settle, grab, read the actual joints; between views move the camera by "
                       "the baseline along a camera-frame direction; return to the start.")
    add_backend_flags(p)
    p.add_argument("--baseline", type=args_.positive("m", cap=MAX_BASELINE_M), default=0.10,
                   help=f"camera move per pair (m, up to {MAX_BASELINE_M})")
    p.add_argument("--direction", default="x",
                   help="camera-frame direction: x, -x, y, -y or dx,dy,dz (default x)")
    p.add_argument("--pairs", type=args_.whole(1, MAX_PAIRS), default=1,
                   help=f"number of pairs (pairs+1 views, up to {MAX_PAIRS})")
    p.add_argument("--out", required=True, help="output recording (.mcap)")
    p.add_argument("--force", action="store_true", help="overwrite --out if it exists")
    p.add_argument("--dry-run", action="store_true", help="print the plan and move nothing")
    p.add_argument("--yes", action="store_true", help="allow live motion without asking")
    add_motion_flags(p)
    p.add_argument("--workspace", default=None,
                   help="base-frame box xmin,xmax,ymin,ymax,zmin,zmax (m) the path must stay in")
    p.add_argument("--image-format", choices=["png", "jpeg"], default="png",
                   help="image compression in the recording (default png, lossless)")
    p.set_defaults(func=run)


def add_motion_flags(p: argparse.ArgumentParser) -> None:
    """--speed, --acceleration and --settle, checked against the hard caps as they are parsed
    (shared by capture and sweep)."""
    p.add_argument("--speed", type=args_.positive("m/s", cap=MAX_LINEAR_SPEED),
                   default=MotionLimits.linear_speed,
                   help=f"linear speed (m/s, default {MotionLimits.linear_speed}, at most "
                   f"{MAX_LINEAR_SPEED})")
    p.add_argument("--acceleration", type=args_.positive("m/s^2", cap=MAX_LINEAR_ACCELERATION),
                   default=MotionLimits.linear_acceleration,
                   help=f"linear acceleration (m/s^2, default {MotionLimits.linear_acceleration}"
                   f", at most {MAX_LINEAR_ACCELERATION})")
    p.add_argument("--settle", type=args_.non_negative("s", cap=MAX_SETTLE_S), default=0.5,
                   help=f"settle time before a shot (s, default 0.5, at most {MAX_SETTLE_S:g})")


def run(args: argparse.Namespace) -> int:
    choice = backend_choice(args)
    out = _output_path(args.out, args.force, args.dry_run)
    model = load_arm_model(args.robot, mount=CameraMount.load(args.mount))
    settings = settings_from_args(args, model)
    arm = backends.build_arm(choice.arm, choice.arm_config, model)
    with arm:
        arm.require_ok()
        kinematics = choose_kinematics(model, arm, live=choice.arm != "mock")
        model = kinematics.model  # plans moves and computes poses with the arm's own table
        plan = plan_capture(model, arm.joint_positions(), settings)
        if args.dry_run or not plan.ok:
            print("\n".join(plan.describe()))
        plan.require_ok()
        if args.dry_run:
            print("dry run: nothing moved")
            return 0
        host = getattr(choice.arm_config, "host", None)
        confirm_live_motion(live=choice.arm != "mock", yes=args.yes,
                            ask=lambda: ask_to_move(f"The {args.robot} at {host} "))
        camera = backends.build_camera(choice.camera, choice.camera_config, model, arm)
        with camera:  # connect checks the device delivers what the (scaled) intrinsics say
            metadata = {**_metadata(args, choice, model), **kinematics.metadata()}
            result = capture_to_file(arm, camera, model, plan, out, metadata,
                                     image_format=args.image_format)
    _print_summary(result, out)
    return 0


def ask_to_move(what: str) -> str | None:
    """Warn and ask for the confirmation word at the terminal; None without a terminal."""
    if not sys.stdin.isatty():
        return None
    print(f"{what}will move. Keep clear and keep the e-stop in reach.")
    return input("Type 'move' to start: ")


def settings_from_args(args: argparse.Namespace, model: ArmModel) -> CaptureSettings:
    direction, label = parse_direction(args.direction)
    limits = MotionLimits(linear_speed=args.speed, linear_acceleration=args.acceleration)
    box = Workspace.parse(args.workspace) if args.workspace else None
    return CaptureSettings(baseline=args.baseline, direction=direction, direction_label=label,
                           pairs=args.pairs, settle_s=args.settle, limits=limits, workspace=box)


def _output_path(text: str, force: bool, dry_run: bool) -> Path:
    out = Path(text)
    if out.is_dir():
        raise ConfigError(f"--out {out} is a directory; give a file name like {out}/rec.mcap")
    if out.exists() and not force and not dry_run:
        raise ConfigError(f"--out {out} exists; pass --force to overwrite it")
    if not out.parent.exists():
        raise ConfigError(f"--out directory {out.parent} does not exist")
    return out


def _metadata(args: argparse.Namespace, choice: BackendChoice,
              model: ArmModel) -> dict[str, str]:
    arm, cam = choice.arm_config, choice.camera_config
    return {
        **model_metadata(model), "arm": args.arm, "host": getattr(arm, "host", None) or "",
        "camera": args.camera, "baseline_m": repr(args.baseline), "direction": args.direction,
        "pairs": str(args.pairs), "speed_m_s": repr(args.speed),
        "acceleration_m_s2": repr(args.acceleration), "settle_s": repr(args.settle),
        "joint_noise_rad": repr(getattr(arm, "joint_noise", 0.0)),
        "camera_noise": repr(getattr(cam, "noise", 0.0)),
        "faults": ",".join(getattr(arm, "faults", ()) or getattr(cam, "faults", ())),
        "mock_profile": getattr(getattr(arm, "profile", None), "name", "")
        or getattr(getattr(cam, "profile", None), "name", ""),
    }


def _print_summary(result: CaptureResult, out: Path) -> None:
    print(f"recorded {result.views} views, {len(result.pairs)} pair(s) -> {out}")
    for p in result.pairs:
        err = (p.achieved_m - p.commanded_m) * 1000
        print(f"  pair {p.pair} (views {p.left_view},{p.right_view}): commanded "
              f"{p.commanded_m * 1000:.2f} mm, achieved {p.achieved_m * 1000:.3f} mm "
              f"({err:+.3f} mm)")
