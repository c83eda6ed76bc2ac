"""``armstereo reconstruct-images``: two photographs without poses -> rectified pair, disparity,
point cloud (metric with --focal and --baseline, projective without)."""

from __future__ import annotations

import argparse
import json
import logging
from pathlib import Path

import cv2
import numpy as np

from armstereo.cli import args as args_
from armstereo.epipolar.features import DETECTORS
from armstereo.epipolar.fundamental import ROBUST_METHODS
from armstereo.epipolar.uncalibrated import ImageReconstruction, reconstruct_images
from armstereo.errors import ConfigError

log = logging.getLogger(__name__)

DESCRIPTIONS = {
    "metric": "metric: metres, in the left view's camera frame (x right, y down, z forward)",
    "similarity": "similarity: the left view's camera frame in units of the (unknown) baseline",
    "projective": "PROJECTIVE: the scene up to an unknown 3D projective transformation; only "
                  "straight lines are meaningful (give --focal and --baseline for metres)",
}


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "reconstruct-images", help="reconstruct from two photographs without recorded poses",
        description="Estimate the epipolar geometry from the images (features + robust F), "
        "rectify (Hartley), match (Birchfield-Tomasi) and triangulate. Metric with --focal and "
        "--baseline (principal point assumed at the image centre, no lens distortion), scaled "
        "by the unknown baseline with --focal only, projective otherwise. Writes points.ply, "
        "disparity.png, rectified.png and report.json into --out.")
    p.add_argument("left", metavar="LEFT", type=args_.input_file,
                   help="first image (any format OpenCV reads)")
    p.add_argument("right", metavar="RIGHT", type=args_.input_file, help="second image, same size")
    p.add_argument("--focal", type=args_.positive("px", cap=1e6), default=None, metavar="PX",
                   help="focal length in pixels (both images)")
    p.add_argument("--baseline", type=args_.positive("m", cap=100.0), default=None, metavar="M",
                   help="distance between the two camera centres in metres (needs --focal)")
    p.add_argument("--out", required=True, metavar="DIR", help="output folder (created)")
    p.add_argument("--detector", choices=DETECTORS, default="sift",
                   help="feature detector (default sift)")
    p.add_argument("--method", choices=ROBUST_METHODS, default="magsac",
                   help="robust fundamental-matrix estimator (default magsac)")
    p.set_defaults(func=run)


def _read(path_text: str) -> np.ndarray:
    path = Path(path_text)
    if not path.is_file():
        raise ConfigError(f"no such image: {path}")
    image = cv2.imread(str(path), cv2.IMREAD_COLOR)
    if image is None:
        raise ConfigError(f"cannot read {path} as an image")
    return image


def _report(rec: ImageReconstruction, args: argparse.Namespace) -> dict:
    rect = rec.rectification
    doc = {"reconstruction": rec.kind, "frame": DESCRIPTIONS[rec.kind],
           "points": int(len(rec.points)), "inlier_matches": int(len(rect.x1)),
           "median_sampson_px": round(rec.median_sampson_px, 4),
           "median_abs_dy_px": round(rect.median_abs_dy_px, 4),
           "disparity_range_px": [round(v, 2) for v in rect.disparity_range],
           "swapped": rect.swapped, "F": rect.F.tolist(),
           "H_left": rect.H_left.tolist(), "H_right": rect.H_right.tolist(),
           "detector": args.detector, "method": args.method}
    if rec.K is not None:
        doc.update(focal_px=args.focal, baseline_m=args.baseline, K=rec.K.tolist(),
                   R_right_left=rec.R.tolist(), t_right_left=rec.t.tolist())
    return doc


def run(args: argparse.Namespace) -> int:
    from armstereo.io.images import colorize_disparity, side_by_side, write_png
    from armstereo.io.ply import write_ply  # moves to armstereo.io.ply (issue 9)

    left, right = _read(args.left), _read(args.right)
    out = Path(args.out)
    if out.exists() and not out.is_dir():
        raise ConfigError(f"--out {out} exists and is not a folder")
    rec = reconstruct_images(left, right, focal_px=args.focal, baseline_m=args.baseline,
                             detector=args.detector, method=args.method)
    out.mkdir(parents=True, exist_ok=True)
    finite = np.all(np.isfinite(rec.points), axis=1)
    write_ply(out / "points.ply", rec.points[finite].astype(np.float32), rec.colors[finite],
              comment=f"armstereo reconstruct-images, {rec.kind}")
    write_png(out / "disparity.png", colorize_disparity(rec.disparity))
    write_png(out / "rectified.png", side_by_side(rec.rectification.left,
                                                  rec.rectification.right))
    (out / "report.json").write_text(json.dumps(_report(rec, args), indent=2) + "\n")
    print(f"{DESCRIPTIONS[rec.kind]}")
    print(f"{int(finite.sum()):,} points, {len(rec.rectification.x1)} inlier matches, median "
          f"Sampson {rec.median_sampson_px:.2f} px, rectified rows agree to "
          f"{rec.rectification.median_abs_dy_px:.2f} px (median); files in {out}/")
    return 0
