"""``armstereo inspect``: what a recording holds and what is wrong with it."""

from __future__ import annotations

import argparse
import json

from armstereo.cli import args as args_
from armstereo.errors import RecordingError
from armstereo.recording import Recording
from armstereo.recording.inspect import format_text, summarize


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("inspect", help="show channels, pairs, calibration and problems of a "
                       "recording",
                       description="Summarise an MCAP recording: channels and message counts, "
                       "duration, stereo pairs with their baselines, calibration, metadata and "
                       "warnings. Exit 0 if it holds a usable stereo pair (a calibration "
                       "recording: a complete view); 5 if it is unreadable or has no complete "
                       "pair with a calibration (the summary is still printed when the file is "
                       "readable).")
    p.add_argument("file", metavar="FILE", type=args_.input_file, help="recording (.mcap)")
    p.add_argument("--json", action="store_true", help="print the summary as JSON (stable keys)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    rec = Recording.open(args.file)
    summary = summarize(rec)
    print(json.dumps(summary, indent=2) if args.json else format_text(summary))
    if rec.start_ns is None:
        raise RecordingError(f"{args.file} holds no readable message")
    from armstereo.calibration.session import PURPOSE, PURPOSE_KEY

    if rec.metadata.get(PURPOSE_KEY) == PURPOSE:  # armstereo calibrate: views, no pairs
        if not rec.views:
            raise RecordingError(f"{args.file} is a calibration recording without a complete "
                                 "view")
        return 0
    rec.require_pairs()
    return 0
