"""``armstereo reconstruct``: recorded pairs -> point clouds, depth and disparity images, MCAP."""

from __future__ import annotations

import argparse
import logging
from pathlib import Path

from armstereo.cli import args as args_
from armstereo.cli.matcher_flags import add_matcher_flags, add_sgbm_flags, matcher_from_args
from armstereo.epipolar.selfcheck import check_pair
from armstereo.errors import ArmstereoError, ConfigError, RecordingError, StereoError
from armstereo.io.files import output_folder
from armstereo.mount import CameraMount
from armstereo.photometric.correct import (
    CHOICES,
    PhotometricOptions,
    for_recording,
    record_json,
)
from armstereo.reconstruct.outputs import write_outputs
from armstereo.reconstruct.pipeline import reconstruct_pair
from armstereo.reconstruct.stereo_options import METHODS
from armstereo.reconstruct.window import check_range
from armstereo.recording import Recording
from armstereo.recording.remount import remounted

log = logging.getLogger("armstereo.reconstruct")


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "reconstruct", help="turn recorded stereo pairs into coloured point clouds",
        description="Rectify each pair from its recorded poses (Fusiello), match it and "
        "triangulate. Writes per pair: PLY (base frame, metres), 16-bit depth PNG (mm, "
        "original left view), colorized disparity, rectified pair with epipolar lines, "
        "depth-error map (if the recording has ground truth) and an MCAP for Foxglove.")
    p.add_argument("recording", metavar="REC.mcap", type=args_.input_file,
                   help="recording made by armstereo capture")
    p.add_argument("--pair", default="all", metavar="K|all",
                   help="pair number in the recording, or 'all' (default)")
    p.add_argument("--out", default=None, metavar="DIR",
                   help="output folder (default: <REC>_reconstruction beside the recording)")
    p.add_argument("--method", choices=METHODS, default="birchfield",
                   help="stereo matcher (default birchfield)")
    p.add_argument("--max-disparity", default="auto", metavar="auto|N",
                   help="disparity budget in pixels; auto derives it from the depth range "
                   "(default)")
    p.add_argument("--near", type=args_.positive("m"), default=None, metavar="M",
                   help="nearest depth of interest in metres (default: from the scene)")
    p.add_argument("--far", type=args_.positive("m"), default=None, metavar="M",
                   help="farthest depth of interest in metres (default: from the scene)")
    p.add_argument("--no-check", action="store_true",
                   help="skip the self-check of each pair's recorded poses against its images "
                   "(armstereo check; a miscalibrated pair is reported as a warning)")
    p.add_argument("--photometric", choices=CHOICES, default="all",
                   help="what is corrected before matching: the camera's vignetting (from the "
                   "recording's mount file, or --mount's) and each pair's exposure and white "
                   "balance (default all; none = the images as recorded)")
    p.add_argument("--mount", default=None, metavar="MOUNT.toml",
                   help="reconstruct as if the camera had this mount (e.g. one written by "
                   "armstereo calibrate after the capture): its hand-eye transform, intrinsics "
                   "and vignetting replace the recorded ones")
    add_matcher_flags(p, names=("photo_check",), help_prefix="birchfield: ")
    add_sgbm_flags(p, help_prefix="sgbm: ")
    p.set_defaults(func=run)


def _max_disparity(text: str) -> int | str:
    if text == "auto":
        return "auto"
    try:
        n = int(text)
    except ValueError:
        raise ConfigError(f"--max-disparity must be 'auto' or a whole number, got {text!r}"
                          ) from None
    if n < 1:
        raise ConfigError(f"--max-disparity must be at least 1, got {n}")
    return n


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
        lost = f"; unreadable: {'; '.join(rec.lost)}" if rec.lost else ""
        raise ConfigError(f"--pair {k} is not in {rec.path.name} (complete pairs: {numbers})"
                          f"{lost}")
    return chosen


def run(args: argparse.Namespace) -> int:
    path = args.recording
    max_disparity = _max_disparity(args.max_disparity)
    check_range(args.near, args.far)  # before any pair is read or checked
    mount = CameraMount.load(args.mount) if args.mount is not None else None
    rec = Recording.open(path)
    pairs = _select(rec, args.pair)
    photometric = PhotometricOptions.from_choice(args.photometric)
    photometric = (photometric.with_model(mount.vignetting) if mount is not None
                   else for_recording(photometric, rec.metadata))
    out = Path(args.out) if args.out else path.with_name(f"{path.stem}_reconstruction")
    # the source's metadata (robot, URDF hash, mount, ...) travels into each output MCAP
    provenance = {k: v for k, v in rec.metadata.items()
                  if k not in ("format_version", "armstereo_version")}
    provenance["source_recording"] = path.name
    if mount is not None:  # the outputs say which camera they were computed with
        provenance.update(mount=mount.name, mount_toml=mount.source)
    failed: list[ArmstereoError] = []
    with output_folder(out):  # nothing reconstructed: no folder left behind
        for pair in pairs:
            if mount is not None:
                pair = remounted(pair, mount)
            if not args.no_check:
                _warn_if_miscalibrated(pair)
            try:
                recon = reconstruct_pair(pair, method=args.method, max_disparity=max_disparity,
                                         near=args.near, far=args.far,
                                         stereo=matcher_from_args(args, args.method),
                                         photometric=photometric)
            except (RecordingError, StereoError) as err:
                if len(pairs) == 1:
                    raise
                log.warning("pair %d: skipped: %s", pair.index, err)
                failed.append(err)
                continue
            meta = {**provenance, "photometric": record_json(recon.photometric)}
            paths = write_outputs(recon, out, f"pair{pair.index:03d}", metadata=meta)
            _report(recon, paths)
        if len(failed) == len(pairs):
            raise type(failed[0])(f"no pair could be reconstructed (first: {failed[0]})")
    if failed:
        # the others are written; the exit code still says that not everything worked
        raise type(failed[0])(f"{len(failed)} of {len(pairs)} pairs skipped (first: "
                              f"{failed[0]}); the others are in {out}")
    return 0


def _warn_if_miscalibrated(pair) -> None:
    """The images are an independent witness of the recorded poses: say when they disagree."""
    try:
        result = check_pair(pair)
    except ArmstereoError as err:  # the check must never stop a reconstruction
        log.warning("pair %d: self-check not possible: %s", pair.index, err)
        return
    if result.verdict == "miscalibrated":
        fix = ("; " + "; ".join(result.correction.describe())) if result.correction else ""
        log.warning("pair %d: the images disagree with the recorded poses (%s)%s; the cloud may "
                    "be bent or misplaced (see armstereo check)", pair.index, result.reason, fix)
    else:
        log.info("pair %d: self-check %s (%s)", pair.index, result.verdict, result.reason)


def _report(recon, paths: dict[str, Path]) -> None:
    plan, t = recon.window, recon.timings_s
    print(f"pair {recon.pair_index}: {len(recon.points_base)} points; left = view "
          f"{recon.left_view}{' (swapped)' if recon.swapped else ''}, "
          f"baseline {recon.rectified.baseline * 1000:.1f} mm")
    print(f"  disparity 0..{plan.max_disparity} px for depth {plan.near:.3f}..{plan.far:.3f} m "
          f"({plan.source}), method {recon.method}")
    stages = " ".join(f"{k} {t[k] * 1000:.0f}" for k in ("decode", "photometric", "rectify",
                                                         "match", "triangulate", "write"))
    print(f"  time: {stages} ms; total {recon.pipeline_time_s * 1000:.0f} ms "
          f"(+{t.get('write_extras', 0.0) * 1000:.0f} ms images and MCAP)")
    photo = recon.photometric
    done = [name for name in ("vignetting", "exposure") if photo.get(name, {}).get("applied")]
    print(f"  photometric: {', '.join(done) or 'nothing'} corrected"
          + (f" (exposure gains {', '.join(f'{g:.3f}' for g in photo['exposure']['gains'])})"
             if "exposure" in done else ""))
    for kind, p in paths.items():
        print(f"  {kind:<12} {p}")
