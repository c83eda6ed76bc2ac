"""``armstereo import BAG --image-topic T --out REC.mcap``: a ROS 2 bag as a recording."""

from __future__ import annotations

import argparse
import json
import os
from pathlib import Path

from armstereo.cli import args as args_
from armstereo.errors import ConfigError


def bag_path(text: str) -> Path:
    """A bag folder (with metadata.yaml) or a bare .mcap / .db3 storage file."""
    path = Path(text)
    if not text.strip():
        raise argparse.ArgumentTypeError("empty path")
    if not path.exists():
        raise argparse.ArgumentTypeError(f"no such bag: {path}")
    if path.is_dir():
        if not (path / "metadata.yaml").is_file():
            raise argparse.ArgumentTypeError(f"{path} is a folder without metadata.yaml, not a "
                                             "ROS 2 bag (give its .mcap or .db3 file)")
        return path
    if path.suffix not in (".mcap", ".db3"):
        raise argparse.ArgumentTypeError(f"{path} is neither a bag folder nor a .mcap or .db3 "
                                         "file")
    if not os.access(path, os.R_OK):
        raise argparse.ArgumentTypeError(f"{path} is not readable (permission denied)")
    return path


def register(sub: argparse._SubParsersAction) -> None:
    from armstereo.cli.calibrate_cmd import parse_board_arg

    p = sub.add_parser(
        "import", help="turn a ROS 2 bag (camera images, /tf or joint states) into a recording",
        description="Read a ROS 2 bag (folder, or .mcap / .db3) with camera images, camera info "
        "and /tf (or joint states with --robot); take a view wherever the camera was at rest, "
        "pair views a baseline apart with capture's motion checks, and write an armstereo "
        "recording that reconstruct, check, calibrate and fuse read. With --board, views that "
        "see the board also go into a calibration recording (calibrate --from). A bag made by "
        "armstereo export keeps its views and pairs. Needs pip install 'armstereo[ros2]'. See "
        "docs/ros2.md.")
    p.add_argument("bag", metavar="BAG", type=bag_path, help="bag folder, .mcap or .db3")
    p.add_argument("--image-topic", required=True, metavar="T",
                   help="sensor_msgs/Image or CompressedImage topic")
    p.add_argument("--camera-info-topic", default=None, metavar="T",
                   help="sensor_msgs/CameraInfo topic (default: camera_info beside the images)")
    p.add_argument("--out", required=True, metavar="REC.mcap", help="recording to write")
    p.add_argument("--force", action="store_true", help="overwrite the output recordings")
    p.add_argument("--baseline", type=args_.positive("m", cap=2.0), default=None, metavar="M",
                   help="pair only consecutive views this far apart (m; default: any baseline "
                   "that passes the motion checks)")
    p.add_argument("--baseline-tolerance", type=args_.positive("m", cap=1.0), default=0.002,
                   metavar="M", help="allowed difference from --baseline (m, default 0.002)")
    p.add_argument("--robot", default=None, metavar="MODEL",
                   help="arm model (ur5e, a URDF or a robot-info --save file): poses from the "
                   "joint states when TF has no chain, and the model of a calibration recording")
    p.add_argument("--mount", default=None, help="camera mount file for poses from the joints "
                   "(default: bundled mount)")
    p.add_argument("--board", type=parse_board_arg, default=None, metavar="SPEC",
                   help="calibration board (as calibrate --board): views that see it go into a "
                   "calibration recording")
    p.add_argument("--calibration-out", default=None, metavar="CALIB.mcap",
                   help="calibration recording to write (default: <out>_calibration.mcap)")
    g = p.add_argument_group("frames and topics")
    g.add_argument("--base-frame", default="base", help="the arm's base frame (default base)")
    g.add_argument("--flange-frame", default="tool0", help="the flange frame (default tool0)")
    g.add_argument("--camera-frame", default=None,
                   help="camera optical frame (default: the images' frame_id)")
    g.add_argument("--tf-topic", default="/tf", metavar="T")
    g.add_argument("--tf-static-topic", default="/tf_static", metavar="T")
    g.add_argument("--joint-states-topic", default="/joint_states", metavar="T")
    g.add_argument("--ignore-events", action="store_true",
                   help="choose views by rest even in a bag made by armstereo export")
    r = p.add_argument_group("camera at rest")
    r.add_argument("--still-window", type=args_.positive("s", cap=60.0), default=0.2,
                   metavar="S", help="how long the camera must be still around an image "
                   "(s, default 0.2)")
    r.add_argument("--still-tolerance", type=args_.positive("m", cap=0.1), default=1e-4,
                   metavar="M", help="how far it may move meanwhile (m, default 0.0001)")
    r.add_argument("--still-angle", type=args_.positive("deg", cap=10.0), default=0.02,
                   metavar="DEG", help="how far it may turn meanwhile (deg, default 0.02)")
    p.add_argument("--json", action="store_true", help="print the report as JSON")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from armstereo.ros2.import_write import check_output
    from armstereo.ros2.importer import ImportOptions, import_bag
    from armstereo.ros2.rest import RestOptions

    out = Path(args.out)
    check_output(out, args.force)
    calib = Path(args.calibration_out) if args.calibration_out else None
    outputs = [out]
    if args.board is not None:
        outputs.append(calib or out.with_name(f"{out.stem}_calibration.mcap"))
        check_output(outputs[-1], args.force, "--calibration-out")
    resolved = [p.resolve() for p in outputs]
    if args.bag.resolve() in resolved or len(set(resolved)) < len(resolved):
        raise ConfigError("the output recordings must differ from each other and from the bag")
    options = ImportOptions(
        image_topic=args.image_topic, camera_info_topic=args.camera_info_topic,
        tf_topic=args.tf_topic, tf_static_topic=args.tf_static_topic,
        joint_states_topic=args.joint_states_topic, base_frame=args.base_frame,
        flange_frame=args.flange_frame, camera_frame=args.camera_frame, robot=args.robot,
        mount=args.mount, baseline=args.baseline, baseline_tolerance=args.baseline_tolerance,
        rest=RestOptions(window_s=args.still_window, still_m=args.still_tolerance,
                         still_deg=args.still_angle),
        board=args.board, calibration_out=calib, use_events=not args.ignore_events)
    report = import_bag(args.bag, out, options)
    if args.json:
        print(json.dumps(report, indent=2))
        return 0
    how = "views and pairs from its capture events" if report["from_events"] else \
        "views where the camera was at rest"
    print(f"{report['bag']} -> {report['out']}: {report['views']} view(s), "
          f"{len(report['pairs'])} pair(s) ({how}; poses from {report['pose_source']}, camera "
          f"frame {report['camera_frame']})")
    for p in report["pairs"]:
        print(f"  pair {p['pair']}: views {p['left_view']}+{p['right_view']}, baseline "
              f"{p['achieved_baseline_m'] * 1000:.2f} mm along {p['direction']}")
    cal = report["calibration"]
    if cal is not None:
        print(f"  calibration: {cal['views']} view(s) see the board"
              + (f" -> {cal['out']} (armstereo calibrate --from {cal['out']})" if cal["out"]
                 else ""))
    for text in report["warnings"]:
        print(f"  warning: {text}")
    return 0
