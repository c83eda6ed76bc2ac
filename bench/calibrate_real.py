"""Real eye-in-hand data recorded elsewhere: held-out prediction error, ours against OpenCV Park.

Data: tests/data/franka_handeye (three 12-view sessions of a Franka Panda with a wrist
RealSense and a 5x7 ChArUco board, MIT; see its README). Sessions a and b were used while
developing issue 25; session c was held out until this benchmark was run.

For every view i: calibrate on the other views, then predict view i's board corners from its
recorded arm pose and compare with what its image shows (px RMS, and mm RMS of the board
corners in the camera frame). Side by side on the same views:

- armstereo: calibrate_from_detections (screening, closed forms on every usable pair, joint
  refinement with the arm's pose error modelled; intrinsics estimated), its X and board pose;
- OpenCV Park: calibrateCamera intrinsics on the training views, PnP, cv2.calibrateHandEye
  (PARK, all pairs), board pose = mean of T_base_flange @ X @ T_camera_board.

"planted" rows: the same session with two faults planted (view 3 given view 4's pose, view 7
given view 6's image); the held-out error is then measured on the ten untouched views.

    .venv/bin/python -m bench.calibrate_real [--out bench/results/calibrate_real.md]
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import cv2
import numpy as np

from armstereo.apps.calibrate_import import import_views
from armstereo.calibration.board import detect_board, parse_board
from armstereo.calibration.calibrate import CalibrationOptions, calibrate_from_detections
from armstereo.calibration.consensus import prediction_error_px
from armstereo.calibration.intrinsics import board_pose, calibrate_intrinsics
from armstereo.calibration.poses import mean_pose
from armstereo.calibration.report import prediction_mm
from armstereo.errors import ArmstereoError
from bench.harness import command_line, machine_note, timed, write_report

DATA = Path(__file__).resolve().parents[1] / "tests" / "data" / "franka_handeye"
BOARD = parse_board("charuco:5x7:0.034:0.028:DICT_6X6_250")
SESSIONS = (("session_a", "development"), ("session_b", "development"),
            ("session_c", "held out"))
# The inner fits run the whole default computation (its leave-one-out chooses the hand-eye).
DEFAULT = CalibrationOptions()


def load(name: str):
    views = import_views(str(DATA / name / "*.png"), DATA / name / "poses.json")
    dets = [detect_board(img, BOARD) for img in views.images]
    size = views.images[0].shape[1::-1]
    return dets, list(views.flanges), size


def plant(dets, flanges):
    dets, flanges = list(dets), list(flanges)
    flanges[3] = flanges[4].copy()
    dets[7] = dets[6]
    return dets, flanges, [k for k in range(len(dets)) if k not in (3, 7)]


def ours(dets, flanges, size):
    cal = calibrate_from_detections(dets, flanges, BOARD, size, options=DEFAULT)
    chosen = cal.report["quality"].get("selection", {}).get("chosen", "refined")
    X = cal.mount.T_flange_camera
    if chosen == "refined":
        B = cal.refined.T_base_board
    else:  # a closed form: its board pose is the kept views' mean, as in the selection
        used = cal.views_used
        B = mean_pose([flanges[k] @ X @ board_pose(dets[k], cal.mount.intrinsics)
                       for k in used])
    return X, B, cal.mount.intrinsics


def park(dets, flanges, size):
    fit = calibrate_intrinsics(dets, size)
    T_cb = [board_pose(d, fit.intrinsics) for d in dets]
    R, t = cv2.calibrateHandEye([F[:3, :3] for F in flanges], [F[:3, 3] for F in flanges],
                                [C[:3, :3] for C in T_cb], [C[:3, 3] for C in T_cb],
                                method=cv2.CALIB_HAND_EYE_PARK)
    X = np.eye(4)
    U, _, Vt = np.linalg.svd(R)
    X[:3, :3], X[:3, 3] = U @ Vt, np.asarray(t).reshape(3)
    B = mean_pose([F @ X @ C for F, C in zip(flanges, T_cb, strict=True)])
    return X, B, fit.intrinsics


def held_out(method, dets, flanges, size, scored):
    """Per scored view: (px, mm) of its prediction by ``method`` fitted without it."""
    out = []
    for i in scored:
        keep = [k for k in range(len(dets)) if k != i and dets[k] is not None]
        try:
            X, B, intr = method([dets[k] for k in keep], [flanges[k] for k in keep], size)
        except ArmstereoError as err:
            out.append((math.inf, math.inf))
            print(f"  fit without view {i} refused: {err}")
            continue
        out.append((prediction_error_px(dets[i], flanges[i], X, B, intr),
                    prediction_mm(dets[i], flanges[i], X, B, intr)))
    return np.array(out)


def row(name: str, kind: str, dets, flanges, size, scored) -> tuple[str, float]:
    full, seconds = timed(calibrate_from_detections, dets, flanges, BOARD, size)
    named = ", ".join(f"{b['view']} ({b['kind']})" for b in full.report["views"]["left_out"])
    a = held_out(ours, dets, flanges, size, scored)
    b = held_out(park, dets, flanges, size, scored)
    ratio = float(np.median(a[:, 0]) / np.median(b[:, 0]))
    q = full.report["quality"]
    chosen = q.get("selection", {}).get("chosen", "refined")
    line = (f"| {name} | {kind} | {len(full.views_used)} / {len(dets)} | {named or 'none'} | "
            f"{chosen} | "
            f"{np.median(a[:, 0]):.2f} px, {np.median(a[:, 1]):.2f} mm | "
            f"{np.median(b[:, 0]):.2f} px, {np.median(b[:, 1]):.2f} mm | **{ratio:.2f}** | "
            f"{q['predicted_error']['translation_m'] * 1000:.2f} mm / "
            f"{q['predicted_error']['rotation_deg']:.3f} deg | "
            f"{full.refined.pose_sigma_t * 1000:.2f} mm | {seconds:.0f} s |")
    return line, ratio


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=None)
    ap.add_argument("--sessions", nargs="*", default=[s for s, _ in SESSIONS],
                    help="which sessions (default all)")
    args = ap.parse_args(argv)
    lines = ["# Real eye-in-hand sessions (bench.calibrate_real)", "",
             "Held-out prediction error: each view predicted from its arm pose by a "
             "calibration fitted without it (median over the scored views). Ratio = "
             "armstereo / OpenCV Park (px); at most 1 is the issue-25 target.", "",
             "| session | data | views used | left out (named) | hand-eye from | "
             "armstereo held-out | OpenCV Park held-out | ratio | predicted error | "
             "arm pose error (est.) | time |", "|---|---|---|---|---|---|---|---|---|---|---|"]
    for name, kind in SESSIONS:
        if name not in args.sessions:
            continue
        dets, flanges, size = load(name)
        scored = [k for k, d in enumerate(dets) if d is not None]
        lines.append(row(name, kind, dets, flanges, size, scored)[0])
        pd, pf, good = plant(dets, flanges)
        lines.append(row(name + " planted", kind + ", 2 faults planted", pd, pf, size,
                         good)[0])
        print("\n".join(lines[-2:]), flush=True)
    lines += ["", "Planted faults: view 3 carries view 4's pose (a pose from another moment), "
              "view 7 carries view 6's image (a stale frame); scored on the ten untouched "
              "views. Images 640x360 grey (half the recorded resolution), intrinsics "
              "estimated from the views, poses as recorded (Franka O_T_EE)."]
    lines += ["", f"`{command_line('bench.calibrate_real', argv)}`; {machine_note()}"]
    write_report("\n".join(lines) + "\n", args.out)


if __name__ == "__main__":
    main()
