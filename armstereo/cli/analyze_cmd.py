"""``armstereo analyze``: a base-frame cloud -> support plane, objects, height map, occupancy."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from armstereo.cli import args as args_
from armstereo.errors import ConfigError
from armstereo.evaluation.scene_score import score_scene
from armstereo.evaluation.scene_truth import SceneTruth
from armstereo.io.files import write_bytes_atomic
from armstereo.scene import SceneOptions, analyze_scene, load_cloud
from armstereo.scene.export import scene_json, write_scene_outputs
from armstereo.scene.report import score_lines, summary

TRUTH_METADATA_KEY = "scene_truth"
DEFAULTS = SceneOptions()


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "analyze", help="find the table, the objects on it and a height map in a cloud",
        description="Fit the support plane (RANSAC + least squares), cluster the points above "
        "it into objects (gravity-aligned box, centre, height, colour, texture each), and build "
        "a height map and an occupancy grid. INPUT is a PLY cloud or an MCAP with /points "
        "(armstereo reconstruct output), in the robot's base frame, metres. Writes scene.json, "
        "scene.mcap (Foxglove), scene_top.png, height_map.npz and occupancy.npz.")
    p.add_argument("input", metavar="INPUT", type=args_.input_file,
                   help="cloud: .ply, or .mcap holding /points")
    p.add_argument("--out", default=None, metavar="DIR",
                   help="output folder (default: <INPUT>_scene beside the input)")
    p.add_argument("--json", action="store_true",
                   help="print scene.json to stdout instead of the summary")
    p.add_argument("--cell", type=args_.positive("m", cap=1.0), default=DEFAULTS.cell_m,
                   metavar="M",
                   help=f"height-map cell (m, default {DEFAULTS.cell_m})")
    p.add_argument("--occupancy-cell", type=args_.positive("m", cap=1.0),
                   default=DEFAULTS.occupancy_cell_m,
                   metavar="M", help="occupancy voxel, a multiple of --cell "
                   f"(m, default {DEFAULTS.occupancy_cell_m})")
    p.add_argument("--up", default="0,0,1", metavar="X,Y,Z",
                   help="expected plane normal in the base frame (default 0,0,1)")
    p.add_argument("--max-tilt", type=args_.fraction(0.0, 90.0), default=DEFAULTS.max_tilt_deg,
                   metavar="DEG",
                   help="largest accepted angle between the plane and --up "
                   f"(default {DEFAULTS.max_tilt_deg:g})")
    p.add_argument("--plane-threshold", type=args_.positive("m", cap=0.5),
                   default=DEFAULTS.plane_threshold_m,
                   metavar="M", help="plane inlier distance; points higher belong to objects "
                   f"(m, default {DEFAULTS.plane_threshold_m})")
    p.add_argument("--min-height", type=args_.non_negative("m", cap=5.0),
                   default=DEFAULTS.min_height_m,
                   metavar="M",
                   help=f"lowest object top above the plane (m, default {DEFAULTS.min_height_m})")
    p.add_argument("--min-size", type=args_.non_negative("m", cap=5.0), default=DEFAULTS.min_size_m,
                   metavar="M",
                   help="smallest footprint width of an object "
                   f"(m, default {DEFAULTS.min_size_m})")
    p.add_argument("--cluster-voxel", type=args_.positive("m", cap=1.0),
                   default=DEFAULTS.cluster_voxel_m,
                   metavar="M", help="voxel edge that links points into one object "
                   f"(m, default {DEFAULTS.cluster_voxel_m})")
    p.add_argument("--flat-min-area", type=args_.non_negative("m^2", cap=10.0),
                   default=DEFAULTS.flat_min_area_m2, metavar="M2",
                   help="smallest sheet lying on the table (paper, a mat) reported as a flat "
                   f"object (m^2, default {DEFAULTS.flat_min_area_m2:g}; 0: none)")
    p.add_argument("--truth", default=None, metavar="TRUTH.json", type=args_.input_file,
                   help="scene truth JSON to score against (default: the recording's "
                   f"'{TRUTH_METADATA_KEY}' metadata, if any); writes scene_score.json")
    p.set_defaults(func=run)


def parse_up(text: str) -> tuple[float, float, float]:
    """``X,Y,Z`` -> a 3-tuple; ConfigError otherwise."""
    try:
        v = tuple(float(x) for x in text.split(","))
    except ValueError:
        raise ConfigError(f"--up must be three numbers X,Y,Z, got {text!r}") from None
    if len(v) != 3:
        raise ConfigError(f"--up must be three numbers X,Y,Z, got {text!r}")
    return v


def run(args: argparse.Namespace) -> int:
    path = Path(args.input)
    options = SceneOptions(up=parse_up(args.up), max_tilt_deg=args.max_tilt,
                           plane_threshold_m=args.plane_threshold, min_height_m=args.min_height,
                           min_size_m=args.min_size, cluster_voxel_m=args.cluster_voxel,
                           cell_m=args.cell, occupancy_cell_m=args.occupancy_cell,
                           flat_min_area_m2=args.flat_min_area)
    options.check()
    truth = _truth(args.truth)
    cloud = load_cloud(path)
    analysis = analyze_scene(cloud, options)
    out = Path(args.out) if args.out else path.with_name(f"{path.stem}_scene")
    paths = write_scene_outputs(analysis, cloud, out)
    if truth is None and TRUTH_METADATA_KEY in cloud.metadata:
        truth = SceneTruth.from_json(cloud.metadata[TRUTH_METADATA_KEY])
    score = None
    if truth is not None:
        score = score_scene(analysis, truth)
        paths["scene_score.json"] = write_bytes_atomic(
            out / "scene_score.json",
            (json.dumps(score.as_dict(), indent=2, allow_nan=False) + "\n").encode())
    if args.json:
        sys.stdout.write(scene_json(analysis))
        return 0
    for line in summary(analysis) + (score_lines(score) if score else []):
        print(line)
    print("files:   " + " ".join(str(p) for p in paths.values()))
    return 0


def _truth(text: str | None) -> SceneTruth | None:
    if text is None:
        return None
    p = Path(text)
    if not p.is_file():
        raise ConfigError(f"--truth: no such file: {p}")
    return SceneTruth.from_json(p.read_text())
