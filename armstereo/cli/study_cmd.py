"""``armstereo study epipolar``: the camera-motion study of the fundamental-matrix estimators."""

from __future__ import annotations

import argparse
import logging
import math
from pathlib import Path

from armstereo.cli import args as args_
from armstereo.errors import ConfigError

log = logging.getLogger(__name__)

STUDIES = ("epipolar",)
MAX_TRIALS = 10_000


def register(sub: argparse._SubParsersAction) -> None:
    from armstereo.epipolar.study import DEFAULT_NOISE_PX, DEFAULT_POINTS, DEFAULT_TRIALS

    p = sub.add_parser(
        "study", help="run a reproducible study (epipolar: estimators vs camera motion)",
        description="epipolar: synthetic cube and point-cloud scenes under rotation-only, "
        "lateral, forward and general camera motion, perfect and noisy points, every "
        "fundamental-matrix estimator; mean and median epipolar, reprojection and truth "
        "errors. Writes study.md, study.csv and study.png. Seeded: same options, same numbers.")
    p.add_argument("study", choices=STUDIES, help="which study")
    p.add_argument("--noise", type=args_.non_negative("px", cap=50.0), default=DEFAULT_NOISE_PX,
                   metavar="PX",
                   help=f"pixel noise (sigma) of the noisy runs (default {DEFAULT_NOISE_PX:g})")
    p.add_argument("--trials", type=args_.whole(1, 10_000), default=DEFAULT_TRIALS, metavar="N",
                   help=f"random scenes per configuration (default {DEFAULT_TRIALS})")
    p.add_argument("--points", type=args_.whole(8, 100_000), default=DEFAULT_POINTS, metavar="N",
                   help=f"points per view (default {DEFAULT_POINTS})")
    p.add_argument("--outliers", type=args_.fraction(0.0, 0.9), default=0.0, metavar="SHARE",
                   help="share of matches replaced by gross outliers, 0..0.9 (default 0)")
    p.add_argument("--seed", type=args_.whole(0, 2**32 - 1), default=0,
                   help="random seed (default 0)")
    p.add_argument("--out", default="epipolar-study", metavar="DIR",
                   help="output folder (default ./epipolar-study)")
    p.set_defaults(func=run)


def _config(args: argparse.Namespace):
    from armstereo.epipolar.study import StudyConfig

    if not (math.isfinite(args.noise) and args.noise >= 0):
        raise ConfigError(f"--noise must be >= 0 px, got {args.noise}")
    if not 1 <= args.trials <= MAX_TRIALS:
        raise ConfigError(f"--trials must lie in 1..{MAX_TRIALS}, got {args.trials}")
    if args.points < 16:
        raise ConfigError(f"--points must be >= 16, got {args.points}")
    if not (math.isfinite(args.outliers) and 0 <= args.outliers <= 0.9):
        raise ConfigError(f"--outliers must lie in 0..0.9, got {args.outliers}")
    return StudyConfig(noise_px=args.noise, trials=args.trials, points=args.points,
                       outliers=args.outliers, seed=args.seed)


def run(args: argparse.Namespace) -> int:
    from armstereo.epipolar.study import run_study, write_study

    config = _config(args)
    out = Path(args.out)
    if out.exists() and not out.is_dir():
        raise ConfigError(f"--out {out} exists and is not a folder")
    rows = run_study(config, progress=log.info)
    paths = write_study(rows, config, out)
    print("wrote " + ", ".join(str(p) for p in paths))
    return 0
