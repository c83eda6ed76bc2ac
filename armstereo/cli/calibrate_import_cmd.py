"""``armstereo calibrate --images GLOB --poses FILE``: the flags and the run (moves nothing).

See :mod:`armstereo.apps.calibrate_import` and docs/calibration.md ("Data recorded elsewhere").
"""

from __future__ import annotations

import argparse
import logging
from pathlib import Path

from armstereo.apps.calibrate import finish
from armstereo.apps.calibrate_import import import_views, parse_tcp_offset, record_imported
from armstereo.calibration.intrinsics_file import read_intrinsics
from armstereo.calibration.pose_import import KINDS
from armstereo.cli import args as args_
from armstereo.errors import ConfigError

log = logging.getLogger("armstereo.calibrate")

IMPORT_ONLY = ("images", "poses", "intrinsics", "tcp")
# Flags of a live session that make no sense for imported data.
NOT_WITH_IMPORT = ("arm", "camera", "mount", "dry_run", "yes", "workspace", "from_recording")


def add_import_flags(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("data recorded elsewhere (moves nothing)")
    g.add_argument("--images", default=None, metavar="GLOB",
                   help="the board images (a glob such as 'calib/*.png', or a directory)")
    g.add_argument("--poses", type=args_.input_file, default=None, metavar="FILE",
                   help="the arm pose of each image (CSV, JSON or YAML: UR TCP 6-vectors, "
                   "4x4 T_base_flange rows, or joint angles with --robot); matched to the "
                   "images by name when it names them, else in order")
    g.add_argument("--pose-format", choices=("auto", *KINDS), default="auto",
                   help="what the numbers are (default auto: 16 or 12 numbers a matrix, 6 "
                   "joints with --robot and a TCP pose without)")
    g.add_argument("--intrinsics", type=args_.input_file, default=None, metavar="FILE",
                   help="hold these intrinsics fixed (mount TOML, ROS camera_info YAML, or "
                   "JSON/YAML with width, height, K, dist); default: estimate them")
    g.add_argument("--tcp", default=None, metavar="X,Y,Z,RX,RY,RZ",
                   help="the TCP offset the TCP poses include (m, rad), taken off to get the "
                   "flange; default zero")


def import_requested(args: argparse.Namespace) -> bool:
    return any(getattr(args, name, None) not in (None, False) for name in IMPORT_ONLY)


def run_import(args: argparse.Namespace, output_path, print_result) -> int:
    """The import run; ``output_path`` and ``print_result`` are calibrate_cmd's helpers."""
    if args.images is None or args.poses is None:
        raise ConfigError("--images and --poses go together (and --intrinsics, --tcp need "
                          "them)")
    given = [f"--{n.replace('_', '-')}" for n in NOT_WITH_IMPORT
             if getattr(args, n, None) not in (None, False)]
    if given:
        raise ConfigError(f"--images/--poses calibrate data recorded elsewhere and move "
                          f"nothing; {', '.join(given)} do(es) not apply")
    if args.board is None:
        raise ConfigError("--board is required with --images (the board in the images)")
    out = output_path(args.out, "--out", args.force, False)
    recording = output_path(args.recording or str(Path(args.out).with_suffix(".mcap")),
                            "--recording", args.force, False)
    if recording.resolve() == out.resolve():
        raise ConfigError(f"--recording and --out are the same file ({out})")
    model = None
    if args.robot:
        from armstereo.robot.model_file import load_arm_model

        model = load_arm_model(args.robot)
    intrinsics = read_intrinsics(args.intrinsics) if args.intrinsics else None
    views = import_views(args.images, args.poses, model=model, pose_format=args.pose_format,
                         T_flange_tcp=parse_tcp_offset(args.tcp))
    if intrinsics is not None and intrinsics.size != views.images[0].shape[1::-1]:
        w, h = views.images[0].shape[1::-1]
        raise ConfigError(f"--intrinsics {args.intrinsics} is for {intrinsics.width}x"
                          f"{intrinsics.height} images, the images are {w}x{h}")
    if recording.exists():
        recording.unlink()  # --force was given (output_path refuses it otherwise)
    record_imported(views, args.board, recording, intrinsics=intrinsics, model=model,
                    images=args.images)
    log.info("recorded %d imported views -> %s; calibrating", len(views.paths), recording)
    cal = finish(recording, out, args.board)
    print_result(args, cal, out, recording)
    return 0
