"""``armstereo demo``: the whole chain on the mock backends, scored against ground truth."""

from __future__ import annotations

import argparse
import logging
import time
from pathlib import Path

from armstereo import backends
from armstereo.apps.demo import DEFAULT_BASELINE_M, DEMO_FILES, DemoOptions, demo_settings, run_demo
from armstereo.apps.scan_demo import SCAN_DEMO_FILES, ScanDemoOptions, run_scan_demo
from armstereo.capture.plan import MAX_BASELINE_M
from armstereo.cli import args as args_
from armstereo.errors import ConfigError
from armstereo.io.files import output_folder
from armstereo.photometric.correct import CHOICES, PhotometricOptions

log = logging.getLogger("armstereo.demo")

TARGET_MEDIAN_REL_ERROR = 0.005
TARGET_DENSITY = 0.90


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("demo", help="capture, reconstruct and score a table scene (no hardware)",
                       description="Capture a table scene with the mock UR5e and mock camera, "
                       "reconstruct it and score the depth against the exact ground truth.")
    p.add_argument("--out", default=None,
                   help="output folder (default: a fresh ./armstereo-demo-<time> folder)")
    p.add_argument("--baseline", type=args_.positive("m", cap=MAX_BASELINE_M), default=None,
                   help=f"camera move between the two views (m, default {DEFAULT_BASELINE_M}; "
                   f"{ScanDemoOptions.baseline} with --scan)")
    p.add_argument("--method", choices=["birchfield", "sgbm"], default="birchfield",
                   help="stereo matcher (default birchfield)")
    p.add_argument("--robot", default="ur5e",
                   help="mock arm model: a model name (default ur5e) or a model file saved by "
                   "robot-info --save")
    p.add_argument("--seed", type=args_.whole(0, 2**32 - 1), default=0,
                   help="scene and noise seed")
    p.add_argument("--mock-profile", choices=backends.mock_profile_names(), default=None,
                   help="how the mock errs: realistic (the default: factory-calibrated arm, a "
                   "camera whose mount file is a CAD guess, image effects, a desk scene) or "
                   "ideal (exact, the table scene)")
    p.add_argument("--no-calibrate", action="store_true",
                   help="skip the camera calibration and use the bundled mount file (what a "
                   "user who never calibrated gets)")
    p.add_argument("--photometric", choices=CHOICES, default="all",
                   help="what is corrected before matching: the camera's vignetting (from the "
                   "mount file) and the pair's exposure and white balance (default all)")
    p.add_argument("--scan", action="store_true",
                   help="scan the scene from several viewpoints (armstereo scan), fuse the pairs "
                   "(armstereo fuse), render the mesh and score it")
    p.add_argument("--views", default=None,
                   help=f"--scan only: viewpoint layout, as armstereo scan takes it (default "
                   f"{ScanDemoOptions.views})")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    if args.scan:
        return run_scan(args)
    if args.views is not None:
        raise ConfigError("--views applies to --scan only")
    options = DemoOptions(robot=args.robot, baseline=args.baseline or DEFAULT_BASELINE_M,
                          method=args.method, seed=args.seed,
                          profile=args.mock_profile or "realistic",
                          calibrate=not args.no_calibrate,
                          photometric=PhotometricOptions.from_choice(args.photometric))
    demo_settings(options)  # bad options fail here, before a folder is made
    out = _out_dir(args.out)
    with output_folder(out):  # a run that fails leaves no empty folder behind
        progress(f"armstereo demo -> {out}/")
        report = run_demo(out, options, progress)
    _print_summary(report, out)
    return 0


def run_scan(args: argparse.Namespace) -> int:
    """``demo --scan``: scan, fuse, render, score (armstereo.apps.scan_demo)."""
    options = ScanDemoOptions(views=args.views or ScanDemoOptions.views,
                              baseline=args.baseline or ScanDemoOptions.baseline,
                              method=args.method, profile=args.mock_profile or "realistic",
                              seed=args.seed, robot=args.robot,
                              calibrate=not args.no_calibrate,
                              photometric=PhotometricOptions.from_choice(args.photometric))
    options.check()
    out = _out_dir(args.out, SCAN_DEMO_FILES)
    with output_folder(out):
        progress(f"armstereo demo --scan -> {out}/")
        report = run_scan_demo(out, options, progress)
    _print_scan_summary(report, out)
    return 0


def _print_scan_summary(report: dict, out: Path) -> None:
    t, acc, mesh = report["timings_s"], report["accuracy"], report["mesh"]
    print(f"cell:     {report['cell']} (camera noise {report['camera_noise']:g} grey levels)")
    _print_calibration(report)
    print(f"scan:     {report['views']}: {report['viewpoints_kept']} viewpoints kept, "
          f"{report['viewpoints_dropped']} dropped; {report['pairs']} pairs, baseline "
          f"{report['baseline_m'] * 1000:.0f} mm at {report['radius_m']:g} m")
    print(f"fused:    {report['voxel_m'] * 1000:g} mm voxels ({report['voxels'] / 1e6:.1f} M), "
          f"mesh {mesh['faces']:,} triangles, fused cloud {report['fused_points']:,} points")
    if acc:
        tg = report["targets"]
        print(f"accuracy: {acc['accuracy_mean_mm']:.3f} mm mean (target <= "
              f"{tg['accuracy_mean_mm']:g} mm), {acc['within_2mm'] * 100:.1f} % within 2 mm; "
              f"raw pairs {acc['raw_pairs']['accuracy_mean_mm']:.3f} mm")
        print(f"complete: {acc['completeness_mean_mm']:.3f} mm mean, "
              f"{acc['completeness_within_5mm'] * 100:.1f} % within 5 mm (target >= "
              f"{tg['completeness_within_5mm'] * 100:.0f} %); F1 @ 2 mm {acc['f1_2mm']:.3f}; "
              f"targets {'met' if tg['met'] else 'MISSED'}")
    before = report.get("before")
    if acc and before and before.get("accuracy"):
        b = before["accuracy"]
        print(f"before/after calibration (the same scan; bundled mount file -> camera.toml): "
              f"accuracy {b['accuracy_mean_mm']:.3f} -> {acc['accuracy_mean_mm']:.3f} mm, "
              f"complete within 5 mm {b['completeness_within_5mm'] * 100:.1f} -> "
              f"{acc['completeness_within_5mm'] * 100:.1f} %")
    stages = ", ".join(f"{k.removeprefix('fuse_')} {v:.1f} s" for k, v in t.items()
                       if k not in ("total", "fuse_total"))
    print(f"time:     {t['total']:.1f} s ({stages})")
    mem = report["memory_mb"]
    print(f"memory:   TSDF {mem['tsdf']:.0f} MB, peak RSS {mem['peak_rss']:.0f} MB")
    extra = (" camera.toml calibration.mcap calibration.json fused_bundled/"
             if report["calibration"] else "")
    print(f"files:    {out}/ scan.mcap fused/ (mesh.ply fused.ply fusion.mcap report.json) "
          f"mesh.png report.json{extra}")


def progress(text: str) -> None:
    """Progress is logged to stderr (quiet with -q); stdout carries only the summary."""
    log.info("%s", text)


def _out_dir(text: str | None, files: tuple[str, ...] = DEMO_FILES) -> Path:
    if text is None:
        out = Path(f"armstereo-demo-{time.strftime('%Y%m%d-%H%M%S')}")
        n = 1
        while out.exists():
            n += 1
            out = Path(f"armstereo-demo-{time.strftime('%Y%m%d-%H%M%S')}-{n}")
        return out
    out = Path(text)
    if out.exists() and not out.is_dir():
        raise ConfigError(f"--out {out} exists and is not a folder")
    clash = [f for f in files if (out / f).exists()]
    if clash:
        raise ConfigError(f"--out {out} already holds demo files ({', '.join(clash)}); "
                          "choose an empty folder")
    return out


def _print_summary(report: dict, out: Path) -> None:
    acc, t = report["accuracy"], report["timings_s"]
    stages = ", ".join(f"{k} {v:.2f} s" for k, v in t.items() if k != "total")
    ok_err = acc["median_abs_rel_depth_error"] <= TARGET_MEDIAN_REL_ERROR
    ok_den = acc["density"] >= TARGET_DENSITY
    kin, check = report["kinematics"], report["check"]
    print(f"cell:     {report['cell'] or report['profile']}")
    _print_calibration(report)
    diff = kin["nominal_vs_calibrated_workspace_max"]
    print(f"arm:      {kin['source']} kinematics"
          + (f" (nominal FK is up to {diff['translation_mm']:.1f} mm / "
             f"{diff['rotation_deg']:.2f} deg away)" if diff else ""))
    fk = check["fk_vs_controller_max_mm"]
    print(f"check:    FK vs controller {fk:.4f} mm" if fk is not None else "check:    -",
          f"({len(check['warnings'])} warning(s))")
    print(f"points:   {report['points']:,}")
    print(f"time:     {t['total']:.1f} s ({stages})")
    print(f"accuracy: median depth error {acc['median_abs_rel_depth_error'] * 100:.3f} % "
          f"(target <= {TARGET_MEDIAN_REL_ERROR * 100:.1f} %: {'met' if ok_err else 'MISSED'}), "
          f"{acc['within_1pct'] * 100:.1f} % of pixels within 1 %, "
          f"density {acc['density'] * 100:.1f} % (target >= {TARGET_DENSITY * 100:.0f} %: "
          f"{'met' if ok_den else 'MISSED'})")
    pe = report["point_error_mm"]
    if pe["median"] is not None:
        print(f"points:   median {pe['median']:.2f} mm from the true surfaces, "
              f"{pe['within_1mm'] * 100:.1f} % within 1 mm")
    _print_scene(report["scene"])
    _print_before_after(report)
    extra = " camera.toml calibration.mcap calibration.json" if report["calibration"] else ""
    print(f"files:    {out}/ points.ply disparity.png rectified.png depth_error.png "
          f"report.json demo.mcap reconstruction.mcap scene/{extra}")


def _print_calibration(report: dict) -> None:
    cal = report["calibration"]
    if cal is None:
        print(f"camera:   {report['mount']['name']} ({report['mount']['file']}, not "
              "calibrated)")
        return
    pred, true = cal["predicted_error"] or {}, cal["truth_error"] or {}
    vig = cal["vignetting"]
    line = (f"camera:   calibrated from {cal['views_used']} views ({cal['rms_px']:.2f} px): "
            f"predicted hand-eye error {pred.get('translation_m', float('nan')) * 1000:.2f} mm"
            f" / {pred.get('rotation_deg', float('nan')):.3f} deg")
    if vig:
        line += f"; vignetting {(1 - min(vig['corner_gain'])) * 100:.0f} % at the corners"
    print(line)
    if true:
        v = true.get("vignetting_corner_rel")
        print(f"          against the cell's truth: {true['translation_m'] * 1000:.2f} mm, "
              f"{true['rotation_deg']:.3f} deg, focal {true['focal_rel'] * 100:+.3f} %"
              + ("" if v is None else f", vignetting at the corners {v * 100:+.1f} %"))


def _print_before_after(report: dict) -> None:
    """Bundled mount file vs calibrated, on the same pair."""
    before = report.get("before")
    if not before:
        return
    after = {"accuracy": report["accuracy"], "point_error_mm": report["point_error_mm"],
             "scene": _scene_numbers(report["scene"]["score"])}
    print("before/after calibration (the same pair; bundled mount file -> camera.toml):")
    for name, key, fmt in (("depth error", "median_abs_rel_depth_error", "{:.3f} %"),
                           ("density", "density", "{:.1f} %")):
        b, a = before["accuracy"][key] * 100, after["accuracy"][key] * 100
        print(f"  {name + ':':<16}{fmt.format(b):>10} -> {fmt.format(a)}")
    b, a = before["point_error_mm"]["median"], after["point_error_mm"]["median"]
    if b is not None and a is not None:
        print(f"  {'points:':<16}{b:>7.2f} mm -> {a:.2f} mm from the true surfaces")
    if "error" in before.get("scene", {}):
        print(f"  {'scene:':<16}no level table with the bundled mount file "
              f"({before['scene']['error']})")
    elif "scene" in before:
        sb, sa = before["scene"], after["scene"]
        print(f"  {'table fit:':<16}{sb['plane_tilt_deg']:>6.2f} deg, "
              f"{sb['plane_height_error_m'] * 1000:+.1f} mm -> {sa['plane_tilt_deg']:.2f} deg, "
              f"{sa['plane_height_error_m'] * 1000:+.1f} mm")
        print(f"  {'objects found:':<16}{sb['objects_found']:>4} of {sb['true_objects']} -> "
              f"{sa['objects_found']} of {sa['true_objects']} (phantoms {sb['phantoms']} -> "
              f"{sa['phantoms']})")


def _scene_numbers(score: dict) -> dict:
    from armstereo.apps.demo_score import scene_summary

    return scene_summary(score)


def _print_scene(scene: dict) -> None:
    """The object table and its score against the mock scene's truth."""
    objects, score = scene["objects"], scene["score"]
    print(f"objects:  {len(objects)} on the table (base frame, mm; heights above the table)")
    for o in objects:
        c, s = (round(v * 1000) for v in o["center_m"]), [round(v * 1000) for v in o["size_m"]]
        print(f"  #{o['id']:<2} centre ({', '.join(map(str, c))})  {s[0]} x {s[1]} x {s[2]}  "
              f"yaw {o['yaw_deg']:+.0f} deg  {o['model']}{' (partial)' if o['partial'] else ''}")
    print("scene vs truth: " + "; ".join(score_summary(score)))


def score_summary(score: dict) -> list[str]:
    """Short phrases from ``scene_score.json``'s keys (objects cut by the view not counted in
    the worst errors)."""
    worst = score["worst"]
    if worst["center_error_m"] is None:
        errors = "no object fully in view to score"
    else:
        errors = (f"worst centre {worst['center_error_m'] * 1000:.1f} mm, height "
                  f"{worst['height_error_m'] * 1000:.1f} mm")
    return [f"{len(score['matched'])} of {score['true_objects']} objects found, phantoms: "
            f"{len(score['phantoms'])}, missed: {', '.join(score['missed']) or 'none'}",
            f"plane tilt {score['plane_tilt_deg']:.3f} deg, height "
            f"{score['plane_height_error_m'] * 1000:+.2f} mm", errors]
