"""``armstereo scan``: stereo pairs from viewpoints around a target, into one recording."""

from __future__ import annotations

import argparse
import logging
import math
from pathlib import Path

from armstereo.apps.scan import ScanOutcome, ScanRequest, backend_metadata, record_scan
from armstereo.capture.plan import MAX_BASELINE_M, Workspace
from armstereo.capture.scan_plan import (
    DEFAULT_ELEVATION_DEG,
    DEFAULT_RADIUS_M,
    MAX_RADIUS_M,
    parse_views,
)
from armstereo.capture.tour import ScanTour
from armstereo.cli import args as args_
from armstereo.cli.backend_flags import add_backend_flags, backend_choice
from armstereo.cli.capture_cmd import _output_path, add_motion_flags, ask_to_move
from armstereo.devices import MotionLimits
from armstereo.errors import ConfigError
from armstereo.mount import CameraMount
from armstereo.robot.model_file import load_arm_model

log = logging.getLogger("armstereo.scan")

DEFAULT_VIEWS = "ring:12"


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("scan", help="shoot a stereo pair from each of several viewpoints around "
                       "a target into one recording",
                       description="Plan viewpoints on a sphere around --target (base frame), "
                       "each a stereo pair with the baseline along the camera's x, drop the "
                       "unreachable ones (saying why), check the whole tour (every move between "
                       "viewpoints too) and capture it into one recording for armstereo fuse.")
    add_backend_flags(p)
    p.add_argument("--target", required=True, type=_point, metavar="X,Y,Z",
                   help="point to look at (base frame, m); write --target=X,Y,Z when X is "
                   "negative")
    p.add_argument("--radius", type=args_.positive("m", cap=MAX_RADIUS_M),
                   default=DEFAULT_RADIUS_M,
                   help=f"camera distance from the target (m, default {DEFAULT_RADIUS_M})")
    p.add_argument("--views", type=_views, default=DEFAULT_VIEWS,
                   help=f"ring:N, sphere:N, grid:RxC, or auto:N (up to N viewpoints chosen "
                   f"while scanning: greedy next-best view; default {DEFAULT_VIEWS})")
    p.add_argument("--elevation", type=args_.fraction(0.0, 90.0), default=DEFAULT_ELEVATION_DEG,
                   help=f"elevation above the target's horizontal plane (deg, default "
                   f"{DEFAULT_ELEVATION_DEG:g}; sphere and grid go from it up)")
    p.add_argument("--baseline", required=True, type=args_.positive("m", cap=MAX_BASELINE_M),
                   help=f"camera move of each pair along the camera's x (m, up to "
                   f"{MAX_BASELINE_M})")
    p.add_argument("--out", required=True, help="output recording (.mcap)")
    p.add_argument("--force", action="store_true", help="overwrite --out if it exists")
    p.add_argument("--dry-run", action="store_true", help="print the plan and move nothing")
    p.add_argument("--yes", action="store_true", help="allow live motion without asking")
    add_motion_flags(p)
    p.add_argument("--workspace", default=None,
                   help="base-frame box xmin,xmax,ymin,ymax,zmin,zmax (m) the flange and camera "
                   "must stay in on every move")
    p.add_argument("--image-format", choices=["png", "jpeg"], default="png",
                   help="image compression in the recording (default png, lossless)")
    p.set_defaults(func=run)


def _point(text: str) -> tuple[float, float, float]:
    try:
        v = tuple(float(s) for s in text.split(","))
    except ValueError:
        v = ()
    if len(v) != 3 or not all(math.isfinite(x) for x in v):
        raise argparse.ArgumentTypeError(f"expected three finite numbers X,Y,Z (m), got {text!r}")
    return v


def _views(text: str) -> str:
    from armstereo.fusion.nbv import parse_auto

    try:
        if parse_auto(text) is None:
            parse_views(text)
    except ConfigError as err:
        raise argparse.ArgumentTypeError(str(err).removeprefix("--views ")) from None
    return text.strip().lower()


def run(args: argparse.Namespace) -> int:
    choice = backend_choice(args)
    out = _output_path(args.out, args.force, args.dry_run)
    model = load_arm_model(args.robot, mount=CameraMount.load(args.mount))
    request = ScanRequest(
        target=args.target, views=args.views, radius=args.radius, elevation_deg=args.elevation,
        baseline=args.baseline, settle_s=args.settle,
        limits=MotionLimits(linear_speed=args.speed, linear_acceleration=args.acceleration),
        workspace=Workspace.parse(args.workspace) if args.workspace else None,
        image_format=args.image_format)
    host = getattr(choice.arm_config, "host", None)
    outcome = record_scan(
        out, request, model, arm=choice.arm, arm_config=choice.arm_config, camera=choice.camera,
        camera_config=choice.camera_config, dry_run=args.dry_run, yes=args.yes,
        ask=lambda: ask_to_move(f"The {args.robot} at {host} "),
        show=lambda tour: _show(tour, full=args.dry_run),
        metadata=backend_metadata(choice.arm, choice.arm_config, choice.camera,
                                  choice.camera_config))
    if args.dry_run:
        print("dry run: nothing moved")
        return 0
    _print_summary(outcome)
    return 0


def _show(tour: ScanTour, *, full: bool) -> None:
    """The whole plan for a dry run or a refused tour; else the headline and what was
    dropped."""
    if full or not tour.ok:
        print("\n".join(tour.describe()))
        return
    lines = tour.scan.describe()
    print("\n".join([lines[0], *(line for line in lines if "dropped viewpoint" in line)]))


def _print_summary(outcome: ScanOutcome) -> None:
    result, out = outcome.result, outcome.out
    print(f"recorded {result.views} views, {len(result.pairs)} pair(s) from "
          f"{len(result.pairs)} viewpoint(s) -> {out}")
    for p in result.pairs:
        err = (p.achieved_m - p.commanded_m) * 1000
        print(f"  pair {p.pair} (views {p.left_view},{p.right_view}) viewpoint {p.viewpoint}: "
              f"baseline commanded {p.commanded_m * 1000:.2f} mm, achieved "
              f"{p.achieved_m * 1000:.3f} mm ({err:+.3f} mm)")
    chosen = getattr(outcome.tour, "chosen", None)
    if chosen is not None:
        print("auto: " + ", ".join(f"viewpoint {c['viewpoint']} ({c['gain_rays']} rays saw "
                                    "unknown space)" for c in chosen)
              + f"; stopped: {outcome.tour.stop_reason}")
    print(f"next: armstereo fuse {out} --out {Path(out).with_suffix('')}_fused")
