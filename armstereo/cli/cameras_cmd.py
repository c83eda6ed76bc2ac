"""``armstereo cameras``: what every installed camera backend can see, as a user's first step
(serial numbers, models, modes), and which backends are missing their extra."""

from __future__ import annotations

import argparse
import json
import sys

from armstereo import backends
from armstereo.errors import ArmstereoError, ConfigError


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "cameras", help="list the cameras every installed backend can see",
        description="List the cameras each camera backend can see now: its --camera spec, "
        "serial number, model, state and modes. A backend whose optional extra is not "
        "installed, or that has no GenTL producer, says so. Exit 0 when the listing ran, "
        "even if no camera was found.")
    p.add_argument("--backend", choices=tuple(backends.CAMERAS), action="append",
                   help="list only this backend (repeatable; default: all)")
    p.add_argument("--cti", default=None, metavar="PATH",
                   help="GenTL producer (.cti file or folder) for the genicam backend "
                   "(default: GENICAM_GENTL64_PATH)")
    p.add_argument("--realsense-playback", default=None, metavar="FILE",
                   help="also list the camera a RealSense recording (.bag, .db3) was made with")
    p.add_argument("--json", action="store_true", help="print JSON instead of text")
    p.set_defaults(func=run)


def survey(names: list[str], options: dict) -> list[dict]:
    """Per backend: ``backend``, ``available`` (False with ``reason`` when it cannot look),
    and its ``cameras``."""
    out = []
    for name in names:
        if name == "mock":
            out.append({"backend": "mock", "available": True, "reason": "", "cameras": [
                {"spec": "mock", "serial": "", "model": "simulated camera (ray-cast scene; the "
                 "default)", "status": "ready", "modes": ["the mount's size"], "note": ""}]})
            continue
        try:
            found = backends.list_cameras(name, options.get(name, {}))
            out.append({"backend": name, "available": True, "reason": "", "cameras": found})
        except ArmstereoError as err:
            out.append({"backend": name, "available": False, "reason": str(err), "cameras": []})
    return out


def _text(rows: list[dict]) -> list[str]:
    lines = []
    for row in rows:
        if not row["available"]:
            lines.append(f"{row['backend']}: unavailable: {row['reason']}")
            continue
        if not row["cameras"]:
            lines.append(f"{row['backend']}: no camera found")
            continue
        lines.append(f"{row['backend']}: {len(row['cameras'])} camera(s)")
        for cam in row["cameras"]:
            what = " ".join(x for x in (cam.get("vendor", ""), cam.get("model", "")) if x)
            lines.append(f"  --camera {cam['spec']}  {what}  [{cam['status']}]".rstrip())
            for key in ("modes", "pixel_formats", "features"):
                if cam.get(key):
                    lines.append(f"      {key.replace('_', ' ')}: {', '.join(cam[key])}")
            if cam.get("note"):
                lines.append(f"      {cam['note']}")
    return lines


def run(args: argparse.Namespace) -> int:
    names = args.backend or list(backends.CAMERAS)
    if args.realsense_playback is not None and "realsense" not in names:
        raise ConfigError("--realsense-playback lists a recording for the realsense backend; "
                          "add --backend realsense")
    options = {"genicam": {"cti": args.cti}, "realsense": {"playback": args.realsense_playback},
               "opencv": {}}
    rows = survey(names, options)
    if args.json:
        json.dump({"backends": rows}, sys.stdout, indent=2)
        print()
    else:
        print("\n".join(_text(rows)))
    return 0
