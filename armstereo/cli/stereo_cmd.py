"""``armstereo stereo``: disparity of an already rectified pair (Middlebury style)."""

from __future__ import annotations

import argparse
import logging
import time
from pathlib import Path

import cv2
import numpy as np

from armstereo.cli import args as args_
from armstereo.cli.matcher_flags import add_matcher_flags, add_sgbm_flags, matcher_from_args
from armstereo.errors import ConfigError
from armstereo.io.disparity import DISPARITY_SUFFIXES, write_disparity
from armstereo.io.images import colorize_disparity, write_png
from armstereo.reconstruct.stereo import METHODS, disparity

log = logging.getLogger(__name__)


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "stereo", help="disparity map of a rectified image pair",
        description="Match a rectified pair: a left pixel (x, y) with disparity d sees the "
        "right pixel (x - d, y). Writes the left image's disparity as .pfm (float, no match = "
        "inf) or .png (16-bit, value = 256 d, 0 = no match). Searched disparities are "
        "MIN .. MIN + N inclusive.")
    p.add_argument("left", metavar="LEFT", type=args_.input_file,
                   help="left (reference) image, 8-bit grey or colour")
    p.add_argument("right", metavar="RIGHT", type=args_.input_file, help="right image, same size")
    p.add_argument("--max-disparity", required=True, type=args_.whole(1, 4096), metavar="N",
                   help="largest disparity searched, counted from --min-disparity (pixels; "
                   "the range MIN .. MIN + N is inclusive)")
    p.add_argument("--out", required=True, metavar="DISP.pfm|.png", help="disparity file")
    p.add_argument("--method", choices=METHODS, default="birchfield",
                   help="matcher (default birchfield; sgbm = OpenCV StereoSGBM)")
    p.add_argument("--min-disparity", type=args_.whole(0, 4096), default=0, metavar="M",
                   help="smallest disparity searched (default 0)")
    p.add_argument("--colorized", metavar="VIEW.png", default=None,
                   help="also write a colour view of the disparity with a legend")
    # the matcher's flags, generated from BirchfieldOptions' fields (their order there)
    add_matcher_flags(p.add_argument_group("birchfield options"),
                      names=("color", "occlusions", "subpixel", "lr_check", "postprocess",
                             "photo_check", "threads"))
    add_sgbm_flags(p.add_argument_group("sgbm options"))
    p.set_defaults(func=run)


def read_image(path: str | Path) -> np.ndarray:
    """8-bit grey (H, W) or BGR (H, W, 3) image; ConfigError if missing or unreadable."""
    if not Path(path).is_file():
        raise ConfigError(f"no such image: {path}")
    img = cv2.imread(str(path), cv2.IMREAD_ANYCOLOR)  # grey stays grey, alpha is dropped
    if img is None:
        raise ConfigError(f"{path}: not a readable image")
    return img


def _check_args(args: argparse.Namespace) -> None:
    for flag, value in (("--out", args.out), ("--colorized", args.colorized)):
        if value is None:
            continue
        suffixes = DISPARITY_SUFFIXES if flag == "--out" else (".png",)
        if Path(value).suffix.lower() not in suffixes:
            raise ConfigError(f"{flag} {value}: use a {' or '.join(suffixes)} file")
        if not Path(value).resolve().parent.is_dir():
            raise ConfigError(f"{flag} {value}: folder does not exist")
    if args.max_disparity < 1:
        raise ConfigError(f"--max-disparity must be at least 1, got {args.max_disparity}")
    if args.min_disparity < 0:
        raise ConfigError(f"--min-disparity must be >= 0, got {args.min_disparity}")
    if args.threads is not None and args.threads < 1:
        raise ConfigError(f"--threads must be at least 1, got {args.threads}")


def run(args: argparse.Namespace) -> int:
    _check_args(args)  # before the (possibly long) matching
    left, right = read_image(args.left), read_image(args.right)
    t0 = time.perf_counter()
    disp = disparity(left, right, args.max_disparity, matcher_from_args(args, args.method),
                     min_disparity=args.min_disparity)
    elapsed = time.perf_counter() - t0
    write_disparity(args.out, disp)
    H, W = disp.shape
    hi = args.min_disparity + args.max_disparity
    print(f"{args.method}: {W}x{H}, disparities {args.min_disparity}..{hi}, "
          f"{100 * np.isfinite(disp).mean():.1f} % matched, {1000 * elapsed:.0f} ms")
    print(f"  disparity  {args.out}")
    if args.colorized:
        write_png(args.colorized, colorize_disparity(disp, args.min_disparity, hi))
        print(f"  colorized  {args.colorized}")
    return 0
