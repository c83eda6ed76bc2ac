"""``armstereo check``: do the images of each recorded pair agree with its recorded poses?"""

from __future__ import annotations

import argparse
import json
import logging
import sys
from pathlib import Path

from armstereo import camera_settings
from armstereo.cli import args as args_
from armstereo.epipolar.features import DETECTORS
from armstereo.epipolar.fundamental import ROBUST_METHODS
from armstereo.epipolar.selfcheck import MISCALIBRATION_THRESHOLD_PX, PairCheck, check_pair
from armstereo.errors import ConfigError
from armstereo.recording import Recording

log = logging.getLogger(__name__)


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "check", help="check each recorded pair's poses against its images",
        description="Match features in each pair, and measure how far the matches lie from "
        "the epipolar lines the recorded poses and intrinsics imply (median Sampson distance). "
        "Verdict per pair: ok, miscalibrated (with the camera offset that explains it) or "
        "inconclusive (the images cannot tell). Warns when the camera took the two views of a "
        "pair at a different exposure, gain or white balance (where it reported them). Exit 0 "
        "whatever the verdicts.")
    p.add_argument("recording", metavar="REC.mcap", type=args_.input_file,
                   help="recording made by armstereo capture")
    p.add_argument("--pair", default="all", metavar="K|all",
                   help="pair number in the recording, or 'all' (default)")
    p.add_argument("--json", action="store_true", help="print JSON instead of text")
    p.add_argument("--threshold", type=args_.positive("px", cap=100.0),
                   default=MISCALIBRATION_THRESHOLD_PX, metavar="PX",
                   help=f"median Sampson distance above which a pair is miscalibrated "
                   f"(default {MISCALIBRATION_THRESHOLD_PX:g} px)")
    p.add_argument("--detector", choices=DETECTORS, default="harris",
                   help="feature detector (default harris)")
    p.add_argument("--method", choices=ROBUST_METHODS, default="magsac",
                   help="robust estimator that removes bad matches (default magsac)")
    p.set_defaults(func=run)


def _select(rec: Recording, which: str) -> list:
    pairs = rec.require_pairs()
    if which == "all":
        return pairs
    try:
        k = int(which)
    except ValueError:
        raise ConfigError(f"--pair must be a pair number or 'all', got {which!r}") from None
    chosen = [p for p in pairs if p.index == k]
    if not chosen:
        numbers = ", ".join(str(p.index) for p in pairs)
        raise ConfigError(f"--pair {k} is not in {rec.path.name} (complete pairs: {numbers})")
    return chosen


def settings_report(pair) -> dict:
    """How the camera settings of a pair's two views compare (:mod:`armstereo.camera_settings`):
    both views' settings, each difference, and a warning for each one the matcher pays for."""
    diffs = camera_settings.compare(pair.left.camera_settings, pair.right.camera_settings)
    return {"left": pair.left.camera_settings, "right": pair.right.camera_settings,
            "differences": [d.as_dict() for d in diffs],
            "warnings": [f"views {pair.left.index} and {pair.right.index}: {d.describe()}"
                         for d in diffs if d.too_large]}


def _text(check: PairCheck) -> list[str]:
    head = f"pair {check.pair}: {check.verdict}"
    if check.median_sampson_px is None:
        return [f"{head} ({check.reason})"]
    image = ("" if check.median_sampson_image_px is None
             else f", {check.median_sampson_image_px:.2f} px under the image-only F")
    lines = [f"{head}: median Sampson distance {check.median_sampson_px:.2f} px under the "
             f"recorded poses{image}; {check.inliers} matches; {check.motion.kind} motion, "
             f"baseline {check.motion.baseline_m * 1000:.1f} mm"]
    if check.verdict == "miscalibrated":
        lines.append(f"  {check.reason}")
        if check.correction is not None:
            lines += [f"  {text}" for text in check.correction.describe()]
    lines += [f"  warning: {w}" for w in check.motion.warnings]
    return lines


def run(args: argparse.Namespace) -> int:
    path = Path(args.recording)
    if not path.is_file():
        raise ConfigError(f"no such recording: {path}")
    if not args.threshold > 0:
        raise ConfigError(f"--threshold must be > 0 px, got {args.threshold}")
    rec = Recording.open(path)
    pairs = _select(rec, args.pair)
    checks = []
    settings = []
    for pair in pairs:
        checks.append(check_pair(pair, detector=args.detector, method=args.method,
                                 threshold_px=args.threshold))
        settings.append(settings_report(pair))
        if not args.json:
            print("\n".join(_text(checks[-1]) + [f"  warning: {w}"
                                                  for w in settings[-1]["warnings"]]))
    if args.json:
        doc = {"recording": path.name, "threshold_px": args.threshold,
               "pairs": [{**c.as_dict(), "camera_settings": st}
                         for c, st in zip(checks, settings, strict=True)]}
        json.dump(doc, sys.stdout, indent=2)
        print()
    return 0
