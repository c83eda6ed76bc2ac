"""``armstereo export REC.mcap --to ros2 --out BAG``: an armstereo recording as a ROS 2 bag."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from armstereo.cli import args as args_

TARGETS = ("ros2",)


def register(sub: argparse._SubParsersAction) -> None:
    from armstereo.ros2.types import DEFAULT_DISTRO, DISTROS

    p = sub.add_parser(
        "export", help="write a recording (any kind) as a ROS 2 bag for ros2 bag play and rviz",
        description="Write an armstereo MCAP (capture, scan, calibration, reconstruction, fusion "
        "or scene) as a rosbag2 bag folder in MCAP storage with the standard ROS 2 messages: "
        "sensor_msgs Image/CompressedImage, CameraInfo, JointState and PointCloud2, tf2_msgs "
        "TFMessage on /tf and /tf_static, visualization_msgs Marker(Array), std_msgs String for "
        "the capture events; time stamps as recorded. Needs pip install 'armstereo[ros2]'. "
        "See docs/ros2.md.")
    p.add_argument("recording", metavar="REC.mcap", type=args_.input_file,
                   help="armstereo recording or output MCAP")
    p.add_argument("--to", required=True, choices=TARGETS, help="target format: ros2")
    p.add_argument("--out", required=True, metavar="BAG", help="bag folder to create")
    p.add_argument("--distro", choices=tuple(DISTROS), default=DEFAULT_DISTRO,
                   help=f"ROS 2 distribution whose message definitions and metadata version "
                   f"the bag carries (default {DEFAULT_DISTRO}: plays on Humble and Jazzy)")
    p.add_argument("--compressed", action="store_true",
                   help="keep the recorded PNG/JPEG as sensor_msgs/CompressedImage on "
                   "<topic>/compressed (default: raw sensor_msgs/Image bgr8)")
    p.add_argument("--camera-frame", default="camera_optical", metavar="FRAME",
                   help="name of the camera's optical frame in the bag (default camera_optical)")
    p.add_argument("--force", action="store_true", help="replace an existing bag folder")
    p.add_argument("--json", action="store_true", help="print the report as JSON")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from armstereo.ros2.export import ExportOptions, export_recording

    options = ExportOptions(distro=args.distro, compressed=args.compressed,
                            camera_frame=args.camera_frame, force=args.force)
    report = export_recording(args.recording, Path(args.out), options)
    if args.json:
        print(json.dumps(report, indent=2))
        return 0
    total = sum(t["messages"] for t in report["topics"].values())
    print(f"{report['kind']} {report['source']} -> ROS 2 bag {report['bag']} "
          f"({report['distro']}, MCAP storage, {total} messages)")
    for topic, info in report["topics"].items():
        print(f"  {topic:<28} {info['type']:<34} {info['messages']}")
    for what, n in report["skipped"].items():
        print(f"  not exported: {n} message(s) on {what}")
    for text in report["warnings"]:
        print(f"  warning: {text}")
    print(f"play it: ros2 bag play {report['bag']}   (rviz: fixed frame 'base'; docs/ros2.md)")
    return 0
