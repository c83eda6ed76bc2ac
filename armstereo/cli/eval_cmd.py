"""``armstereo eval``: score a disparity map against ground truth (Middlebury-style rates)."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import cv2
import numpy as np

from armstereo.cli import args as args_
from armstereo.errors import ConfigError, StereoError
from armstereo.evaluation.disparity import evaluate_disparity
from armstereo.io.disparity import read_disparity

MASK_THRESHOLD = 128  # Middlebury masks: 255 scored, 128 occluded, 0 unknown
META_FILE = "meta.json"  # tests/data/middlebury layout: {"gt": file name, "gt_scale": s}


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "eval", help="bad-pixel rates and average error of a disparity map",
        description="Compare a left-image disparity map with ground truth on the pixels where "
        "the truth is known (and MASK is white). bad-1/bad-2: share of those pixels whose "
        "error exceeds 1/2 px or that have no disparity; average error over the pixels that "
        "have one; invalid: share without a disparity. Files: .pfm as stored; .png divided by "
        "its scale, 0 = unknown (16-bit: 256 unless told; 8-bit: 1 unless told).")
    p.add_argument("disp", metavar="DISP", type=args_.input_file,
                   help="disparity to score (.pfm or .png)")
    p.add_argument("gt", metavar="GT", type=args_.input_file,
                   help="ground-truth disparity (.pfm or .png)")
    p.add_argument("--mask", metavar="MASK", default=None, type=args_.input_file,
                   help="image; only its white pixels (> 128) are scored, as in Middlebury's "
                   "masks (e.g. nonocc.png; grey 128 marks occluded pixels there)")
    p.add_argument("--gt-scale", type=args_.positive("per px"), default=None, metavar="S",
                   help="GT PNG value per pixel of disparity (Middlebury v2: Tsukuba 16, "
                   "Venus 8, Teddy and Cones 4). Default: 'gt_scale' of a meta.json beside "
                   "GT that names it, else the PNG default above")
    p.add_argument("--disp-scale", type=args_.positive("per px"), default=None, metavar="S",
                   help="DISP PNG value per pixel of disparity (default as above)")
    p.add_argument("--exclude-left", type=args_.whole(0, 100_000), default=0, metavar="N",
                   help="leave out the left band of N columns (where a matcher searching up "
                   "to N px has no partner); default 0")
    p.add_argument("--json", action="store_true", help="print the scores as JSON")
    p.set_defaults(func=run)


def gt_scale_from_meta(gt_path: Path) -> float | None:
    """``gt_scale`` from a ``meta.json`` beside ``gt_path`` that names that file, else None."""
    meta_path = gt_path.with_name(META_FILE)
    if not meta_path.is_file():
        return None
    try:
        meta = json.loads(meta_path.read_text())
    except (OSError, ValueError) as err:
        raise ConfigError(f"{meta_path}: unreadable ({err})") from err
    if not isinstance(meta, dict) or meta.get("gt") != gt_path.name or "gt_scale" not in meta:
        return None
    return float(meta["gt_scale"])


def read_mask(path: str | Path, shape: tuple[int, int]) -> np.ndarray:
    """Bool mask (white, > :data:`MASK_THRESHOLD`, = scored) of the size ``shape``;
    ConfigError otherwise."""
    if not Path(path).is_file():
        raise ConfigError(f"no such mask: {path}")
    mask = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE)
    if mask is None:
        raise ConfigError(f"{path}: not a readable image")
    if mask.shape != shape:
        raise ConfigError(f"mask {path} is {mask.shape[1]}x{mask.shape[0]}, the ground truth "
                          f"{shape[1]}x{shape[0]}")
    return mask > MASK_THRESHOLD


def _read(path: str | Path, scale: float | None, what: str) -> np.ndarray:
    try:
        return read_disparity(path, scale=scale)
    except StereoError as err:  # not a disparity file: bad input, like a missing one
        raise ConfigError(f"{what} file: {err}") from None


def format_scores(scores: dict) -> str:
    return "\n".join([
        f"bad-1          {100 * scores['bad1']:6.2f} %",
        f"bad-2          {100 * scores['bad2']:6.2f} %",
        f"average error  {scores['avg_error']:6.3f} px",
        f"invalid        {100 * scores['invalid']:6.2f} %",
        f"scored pixels  {scores['pixels']}",
    ])


def run(args: argparse.Namespace) -> int:
    if args.exclude_left < 0:
        raise ConfigError(f"--exclude-left must be >= 0, got {args.exclude_left}")
    gt_scale = args.gt_scale if args.gt_scale is not None else gt_scale_from_meta(Path(args.gt))
    gt = _read(args.gt, gt_scale, "ground-truth")
    disp = _read(args.disp, args.disp_scale, "disparity")
    if disp.shape != gt.shape:
        raise ConfigError(f"{args.disp} is {disp.shape[1]}x{disp.shape[0]}, the ground truth "
                          f"{args.gt} {gt.shape[1]}x{gt.shape[0]}")
    mask = read_mask(args.mask, gt.shape) if args.mask else None
    scores = evaluate_disparity(disp, gt, mask, exclude_left=args.exclude_left)
    if args.json:
        # NaN (nothing matched) is not JSON: null
        print(json.dumps({k: None if v != v else v for k, v in scores.items()}, indent=2))
    else:
        print(format_scores(scores))
    return 0
