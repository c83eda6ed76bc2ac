"""``armstereo plan``: recommend a baseline for a depth range and accuracy."""

from __future__ import annotations

import argparse
import json

from armstereo.apps.baseline import recommend_baseline
from armstereo.cli import args as args_
from armstereo.mount import CameraMount


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("plan", help="recommend a baseline from depth range and accuracy",
                       description="Recommend a baseline from dZ = Z^2 dd / (f b), the "
                       "disparity budget and the overlap of the two views.")
    p.add_argument("--near", type=args_.positive("m"), required=True,
                   help="nearest depth of interest (m)")
    p.add_argument("--far", type=args_.positive("m"), required=True,
                   help="farthest depth of interest (m)")
    p.add_argument("--depth-accuracy", type=args_.positive("m"), required=True,
                   help="wanted depth accuracy at --far (m)")
    p.add_argument("--mount", default=None, help="camera mount file (default: bundled mount)")
    p.add_argument("--max-disparity", type=args_.whole(1, 4096), default=64,
                   help="matcher's disparity budget in pixels (default 64)")
    p.add_argument("--disparity-precision", type=args_.positive("px"), default=0.25,
                   help="expected disparity error in pixels (default 0.25, subpixel matching)")
    p.add_argument("--min-overlap", type=args_.fraction(0.0, 1.0), default=0.6,
                   help="least share of the image both views must see at --near (default 0.6)")
    p.add_argument("--direction", choices=["x", "y"], default="x",
                   help="camera axis the baseline runs along (sets the image extent used)")
    p.add_argument("--json", action="store_true", help="print the plan as JSON")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    intr = CameraMount.load(args.mount).intrinsics
    focal = intr.fx if args.direction == "x" else intr.fy
    extent = intr.width if args.direction == "x" else intr.height
    plan = recommend_baseline(args.near, args.far, args.depth_accuracy, focal_px=focal,
                         extent_px=extent, max_disparity=args.max_disparity,
                         disparity_precision=args.disparity_precision,
                         min_overlap=args.min_overlap)
    if args.json:
        print(json.dumps(plan.as_dict(), indent=2))
        return 0
    print(f"recommended baseline: {plan.baseline_m * 1000:.0f} mm along camera {args.direction}")
    print(f"  admissible:         {plan.min_baseline_m * 1000:.1f} .. "
          f"{plan.max_baseline_m * 1000:.1f} mm (upper limit set by the {plan.limited_by})")
    print(f"  disparity range:    {plan.disparity_far_px:.1f} .. {plan.disparity_near_px:.1f} px "
          f"({plan.disparity_range_px:.1f} px of a {args.max_disparity} px budget)")
    print(f"  depth accuracy:     {plan.accuracy_near_m * 1000:.2f} mm at {plan.near_m} m, "
          f"{plan.accuracy_far_m * 1000:.2f} mm at {plan.far_m} m "
          f"(for {plan.disparity_precision_px} px disparity error)")
    print(f"  overlap:            {plan.overlap_near:.0%} at {plan.near_m} m, "
          f"{plan.overlap_far:.0%} at {plan.far_m} m")
    return 0
