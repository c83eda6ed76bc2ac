"""``armstereo capture``: stop-and-shoot capture of stereo pairs into an MCAP recording."""

from __future__ import annotations

import argparse
import contextlib
import logging
import signal
import sys
from pathlib import Path

from armstereo.capture import CaptureSettings, Workspace, plan_capture, run_capture
from armstereo.capture.backends import ARM_KINDS, build_arm, build_camera
from armstereo.capture.plan import parse_direction
from armstereo.capture.run import CaptureResult, model_metadata
from armstereo.devices import MotionLimits
from armstereo.errors import ArmstereoError, ConfigError, UserAbort
from armstereo.kinematics import MODEL_NAMES, ArmModel
from armstereo.mount import CameraMount

log = logging.getLogger("armstereo.capture")


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("capture", help="move the camera by a baseline and record stereo pairs",
                       description="Stop-and-shoot capture: at each view wait until steady, "
                       "settle, grab, read the actual joints; between views move the camera by "
                       "the baseline along a camera-frame direction; return to the start.")
    add_backend_args(p)
    p.add_argument("--baseline", type=float, default=0.10, help="camera move per pair (m)")
    p.add_argument("--direction", default="x",
                   help="camera-frame direction: x, -x, y, -y or dx,dy,dz (default x)")
    p.add_argument("--pairs", type=int, default=1, help="number of pairs (pairs+1 views)")
    p.add_argument("--out", required=True, help="output recording (.mcap)")
    p.add_argument("--force", action="store_true", help="overwrite --out if it exists")
    p.add_argument("--dry-run", action="store_true", help="print the plan and move nothing")
    p.add_argument("--yes", action="store_true", help="allow live motion without asking")
    p.add_argument("--speed", type=float, default=MotionLimits.linear_speed,
                   help=f"linear speed cap (m/s, default {MotionLimits.linear_speed})")
    p.add_argument("--acceleration", type=float, default=MotionLimits.linear_acceleration,
                   help=f"linear acceleration (m/s^2, default {MotionLimits.linear_acceleration})")
    p.add_argument("--settle", type=float, default=0.5, help="settle time before a shot (s)")
    p.add_argument("--workspace", default=None,
                   help="base-frame box xmin,xmax,ymin,ymax,zmin,zmax (m) the path must stay in")
    p.add_argument("--image-format", choices=["png", "jpeg"], default="png",
                   help="image compression in the recording (default png, lossless)")
    p.set_defaults(func=run)


def add_backend_args(p: argparse.ArgumentParser) -> None:
    """Arm, camera and mock options shared by capture, demo and sweep."""
    p.add_argument("--arm", choices=ARM_KINDS, default="mock", help="arm backend (default mock)")
    p.add_argument("--host", default=None, help="UR controller address (with --arm ur)")
    p.add_argument("--camera", default="mock", help="mock or opencv:<index-or-path>")
    p.add_argument("--robot", default="ur5e", help=f"arm model: {', '.join(MODEL_NAMES)} or URDF")
    p.add_argument("--mount", default=None, help="camera mount file (default: bundled mount)")
    p.add_argument("--inject-fault", action="append", default=[], metavar="NAME[@N]",
                   help="mock backends only: disconnect, protective-stop, camera-timeout, "
                   "stuck-move (N = which move or grab)")
    p.add_argument("--joint-noise", type=float, default=0.0,
                   help="mock arm: joint repeatability noise, rad (default 0)")
    p.add_argument("--camera-noise", type=float, default=0.0,
                   help="mock camera: sensor noise sigma in grey levels (default 0)")
    p.add_argument("--realtime", action="store_true",
                   help="mock arm: move in real time instead of simulated time")
    p.add_argument("--seed", type=int, default=0, help="seed for the mock backends' noise")


def run(args: argparse.Namespace) -> int:
    out = _output_path(args.out, args.force, args.dry_run)
    model = ArmModel.load(args.robot, mount=CameraMount.load(args.mount))
    settings = settings_from_args(args, model)
    faults = _faults(args)
    arm = build_arm(args.arm, model, host=args.host, realtime=args.realtime,
                    joint_noise=args.joint_noise, faults=faults, seed=args.seed)
    with arm:
        arm.require_ok()
        plan = plan_capture(model, arm.joint_positions(), settings)
        if args.dry_run or not plan.ok:
            print("\n".join(plan.describe()))
        plan.require_ok()
        if args.dry_run:
            print("dry run: nothing moved")
            return 0
        _confirm_motion(args)
        camera = build_camera(args.camera, model, arm, faults=faults, noise=args.camera_noise,
                              seed=args.seed)
        with camera:
            _check_camera(camera, model)
            result = capture_to_file(arm, camera, model, plan, out, _metadata(args, model),
                                     image_format=args.image_format)
    _print_summary(result, out)
    return 0


def settings_from_args(args: argparse.Namespace, model: ArmModel) -> CaptureSettings:
    direction, label = parse_direction(args.direction)
    limits = MotionLimits(linear_speed=args.speed, linear_acceleration=args.acceleration)
    box = Workspace.parse(args.workspace) if args.workspace else None
    return CaptureSettings(baseline=args.baseline, direction=direction, direction_label=label,
                           pairs=args.pairs, settle_s=args.settle, limits=limits, workspace=box)


def capture_to_file(arm, camera, model, plan, out: Path, metadata: dict[str, str],
                    image_format: str = "png", progress=log.info) -> CaptureResult:
    """Run the capture into ``out``; the file is finished whatever happens (even SIGTERM)."""
    from armstereo.recording import RecordingWriter

    result = CaptureResult()
    with _sigterm_as_interrupt(), RecordingWriter(out, metadata=metadata,
                                                  image_format=image_format) as writer:
        try:
            run_capture(arm, camera, model, plan, writer, progress=progress, result=result)
        except ArmstereoError as err:
            err.args = (f"{err}; {result.views} view(s) kept in {out}",)
            raise
        except KeyboardInterrupt:
            raise UserAbort(f"interrupted; {result.views} view(s) kept in {out}") from None
    return result


def _output_path(text: str, force: bool, dry_run: bool) -> Path:
    out = Path(text)
    if out.is_dir():
        raise ConfigError(f"--out {out} is a directory; give a file name like {out}/rec.mcap")
    if out.exists() and not force and not dry_run:
        raise ConfigError(f"--out {out} exists; pass --force to overwrite it")
    if not out.parent.exists():
        raise ConfigError(f"--out directory {out.parent} does not exist")
    return out


def _faults(args: argparse.Namespace):
    if not args.inject_fault:
        return None
    if args.arm != "mock" and args.camera != "mock":
        raise ConfigError("--inject-fault works with the mock arm or mock camera only")
    from drivers.mock.faults import FaultPlan

    return FaultPlan.parse(args.inject_fault)


def _confirm_motion(args: argparse.Namespace) -> None:
    """Live motion (a real arm) needs --yes or the word 'move' typed at a terminal."""
    if args.arm == "mock" or args.yes:
        return
    if not sys.stdin.isatty():
        raise UserAbort("live motion needs --yes or a typed confirmation (stdin is not a terminal)")
    print(f"The {args.robot} at {args.host} will move. Keep clear and keep the e-stop in reach.")
    answer = input("Type 'move' to start: ").strip().lower()
    if answer != "move":
        raise UserAbort("not confirmed; nothing moved")


def _check_camera(camera, model: ArmModel) -> None:
    got, want = camera.intrinsics.size, model.mount.intrinsics.size
    if got != want:
        raise ConfigError(f"camera delivers {got[0]}x{got[1]} but the mount says "
                          f"{want[0]}x{want[1]}; fix the mount file")


def _metadata(args: argparse.Namespace, model: ArmModel) -> dict[str, str]:
    return {
        **model_metadata(model), "arm": args.arm, "host": args.host or "", "camera": args.camera,
        "baseline_m": repr(args.baseline), "direction": args.direction,
        "pairs": str(args.pairs), "speed_m_s": repr(args.speed),
        "acceleration_m_s2": repr(args.acceleration), "settle_s": repr(args.settle),
        "joint_noise_rad": repr(args.joint_noise), "camera_noise": repr(args.camera_noise),
        "faults": ",".join(args.inject_fault),
    }


def _print_summary(result: CaptureResult, out: Path) -> None:
    print(f"recorded {result.views} views, {len(result.pairs)} pair(s) -> {out}")
    for p in result.pairs:
        err = (p.achieved_m - p.commanded_m) * 1000
        print(f"  pair {p.pair} (views {p.left_view},{p.right_view}): commanded "
              f"{p.commanded_m * 1000:.2f} mm, achieved {p.achieved_m * 1000:.3f} mm "
              f"({err:+.3f} mm)")


@contextlib.contextmanager
def _sigterm_as_interrupt():
    """Treat SIGTERM like Ctrl-C so the arm stops and the recording is finished."""
    def handler(signum, frame):
        raise KeyboardInterrupt

    try:
        previous = signal.signal(signal.SIGTERM, handler)
    except ValueError:  # not the main thread (e.g. called from a test thread)
        yield
        return
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)
