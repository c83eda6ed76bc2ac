"""``armstereo fuse``: reconstruct every pair of a scan and fuse them into one model."""

from __future__ import annotations

import argparse
import json
import logging

from armstereo.cli import args as args_
from armstereo.fusion.run import (
    DEFAULT_VOXEL_M,
    TRUNC_VOXELS,
    FusionOptions,
    FusionProgress,
    fuse_recording,
)
from armstereo.fusion.tsdf import Roi
from armstereo.io.files import output_folder
from armstereo.photometric.correct import CHOICES, PhotometricOptions
from armstereo.reconstruct.stereo import METHODS

log = logging.getLogger("armstereo.fuse")


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("fuse", help="fuse every stereo pair of a recording into a mesh",
                       description="Reconstruct every pair of SCAN.mcap and fuse the depth maps "
                       "into a TSDF over a region of interest (base frame); write mesh.ply, "
                       "fused.ply (points seen by two pairs or more), fusion.mcap and "
                       "report.json into --out. Recordings with scene truth are scored.")
    p.add_argument("recording", metavar="SCAN.mcap", type=args_.input_file,
                   help="recording with one or more pairs")
    p.add_argument("--out", required=True, help="output folder")
    p.add_argument("--voxel", type=args_.positive("m", cap=0.1), default=DEFAULT_VOXEL_M,
                   help=f"voxel edge (m, default {DEFAULT_VOXEL_M})")
    p.add_argument("--trunc", type=args_.positive("m", cap=1.0), default=None,
                   help=f"truncation distance (m, default {TRUNC_VOXELS} voxels)")
    p.add_argument("--roi", default=None, metavar="xmin,xmax,ymin,ymax,zmin,zmax",
                   help="region of interest in the base frame (m; default: where the views "
                   "agree)")
    p.add_argument("--method", choices=METHODS, default="birchfield", help="stereo matcher")
    p.add_argument("--depth-source", choices=("stereo", "truth"), default="stereo",
                   help="stereo (default) or the mock camera's ground-truth depth (a check of "
                   "the fusion itself)")
    p.add_argument("--workers", type=args_.whole(1, 64), default=None,
                   help="reconstruction processes (default: one per two cores)")
    p.add_argument("--photometric", choices=CHOICES, default="all",
                   help="what is corrected before matching: the camera's vignetting (from the "
                   "recording's mount file) and each pair's exposure and white balance "
                   "(default all)")
    p.add_argument("--json", action="store_true", help="print the report as JSON")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    roi = Roi.parse(args.roi) if args.roi else None
    options = FusionOptions(voxel=args.voxel, trunc=args.trunc, roi=roi, method=args.method,
                            depth_source=args.depth_source, workers=args.workers,
                            photometric=PhotometricOptions.from_choice(args.photometric))
    with output_folder(args.out):  # a fusion that fails early leaves no empty folder
        report = fuse_recording(args.recording, args.out, options,
                                progress=None if args.json else _progress)
    if args.json:
        print(json.dumps(report, indent=2))
    else:
        print("\n".join(summary_lines(report)))
    return 0


def _progress(event: FusionProgress) -> None:
    log.info("%s pair %d (%d/%d) %.2f s%s", event.stage, event.pair, event.done, event.total,
             event.seconds, f": {event.detail}" if event.detail else "")


def summary_lines(report: dict) -> list[str]:
    """The human-readable summary of a fusion report."""
    mesh = report["mesh"]
    lines = [f"fused {report['views']} pair(s) at {report['voxel_m'] * 1000:g} mm voxels "
             f"({report['voxels'] / 1e6:.1f} M voxels, {report['memory_mb']['tsdf']:.0f} MB; "
             f"region {report['roi_source']}: "
             + ",".join(f"{v:.3f}" for v in report["roi_m"]) + " m)",
             f"  mesh: {mesh['faces']} triangles, {mesh['area_m2'] * 1e4:.0f} cm^2; fused cloud: "
             f"{report['fused_points']} points (dropped {report['single_view_points']} seen by "
             "one pair only)"]
    acc = report.get("accuracy")
    if acc:
        lines.append(f"  accuracy {acc['accuracy_mean_mm']:.3f} mm (within 2 mm "
                     f"{acc['within_2mm'] * 100:.1f} %), completeness "
                     f"{acc['completeness_mean_mm']:.3f} mm (within 5 mm "
                     f"{acc['completeness_within_5mm'] * 100:.1f} %), F1@2mm {acc['f1_2mm']:.3f}; "
                     f"raw pairs {acc['raw_pairs']['accuracy_mean_mm']:.3f} mm")
    t = report["timings_s"]
    lines.append("  time: " + ", ".join(f"{k} {v:.2f} s" for k, v in t.items()))
    lines.append("  wrote " + ", ".join(report["outputs"].values()))
    return lines
