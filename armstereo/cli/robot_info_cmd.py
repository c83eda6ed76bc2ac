"""``armstereo robot-info``: a UR arm's own calibrated kinematics, read-only, and how far its
nominal model is from them."""

from __future__ import annotations

import argparse
import json
import logging

import numpy as np

from armstereo import backends
from armstereo.cli import args as args_
from armstereo.errors import ConfigError, HardwareError
from armstereo.robot.dh import (
    FKDifference,
    fk,
    fk_difference,
    nominal_table,
    pose_difference,
    ur_calibration_hash,
)
from armstereo.robot.model_file import is_model_file, load_model_file, save_model_file
from armstereo.transforms import T_from_ur_pose

log = logging.getLogger(__name__)

READ_ONLY_PORTS = (30011, 30012)  # the primary/secondary ports that cannot run commands
DEFAULT_TIMEOUT_S = 2.0
MAX_TIMEOUT_S = 60.0
NO_TABLE_EXIT = HardwareError.exit_code


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "robot-info", help="read a UR arm's own calibrated kinematics (read-only)",
        description="Read the calibrated DH table a UR controller broadcasts on its read-only "
        "secondary port (30012; nothing is ever sent to the controller) and print the arm's "
        "model, software version, calibration status and hash, the table, and how far the "
        "nominal model's forward kinematics is from the calibrated one at the current joints. "
        f"Exit 0 when the controller's table was read, {NO_TABLE_EXIT} when it was not (the "
        "nominal model is shown, with the reason).")
    p.add_argument("--host", required=True, type=args_.host,
                   help="the controller's IP address or name")
    p.add_argument("--json", action="store_true", help="print the result as JSON (stable keys)")
    p.add_argument("--save", metavar="FILE", default=None,
                   help="save the calibrated model to FILE (.json) for --robot FILE")
    p.add_argument("--robot", default=None,
                   help="the model you expect (ur3e, ur5e, ur10e, ur16e, ur5), refused if the "
                   "controller's kinematics are another model's (default: identify it); or a "
                   "model file saved by --save: then it also says whether that file is still "
                   "this arm's table")
    p.add_argument("--port", type=int, choices=READ_ONLY_PORTS, default=READ_ONLY_PORTS[1],
                   help="read-only port: 30012 secondary (default) or 30011 primary")
    p.add_argument("--timeout", type=args_.positive("s", cap=MAX_TIMEOUT_S),
                   default=DEFAULT_TIMEOUT_S,
                   help="seconds to wait for the table (default %(default)s)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    if args.save and not str(args.save).lower().endswith(".json"):
        raise ConfigError(f"--save {args.save}: a robot model file ends in .json")
    saved = load_model_file(args.robot).table if args.robot and is_model_file(args.robot) \
        else None
    result = _read(args.host, saved.model if saved else args.robot, args.port, args.timeout)
    summary = summarize(result, args.host, args.port)
    if saved is not None:
        summary["robot_file_matches"] = bool(result.calibrated
                                             and result.table.sha256 == saved.sha256)
        if not summary["robot_file_matches"]:
            summary["warnings"].append(
                f"--robot {args.robot} (sha256 {saved.sha256[:12]}) is not the table this "
                f"controller reports" + ("" if result.calibrated else " (none was read)"))
    if args.save and result.calibrated:
        version = summary["software_version"] or ""
        summary["saved_to"] = str(save_model_file(args.save, result.table, host=args.host,
                                                  software_version=version))
    print(json.dumps(summary, indent=2) if args.json else format_text(summary))
    if not result.calibrated:
        reason = summary["warnings"][0] if summary["warnings"] else "no calibrated table read"
        saved = f"; nothing saved to {args.save}" if args.save else ""
        raise HardwareError(f"no calibrated kinematics from {args.host}: {reason}{saved}")
    for warning in summary["warnings"]:
        log.warning("warning: %s", warning)
    return 0


def _read(host: str, robot: str | None, port: int, timeout: float):
    return backends.read_ur_kinematics(host, robot, port=port, timeout=timeout)


def summarize(result, host: str, port: int) -> dict:
    """The JSON-ready summary of a read (``drivers.ur.primary.ArmKinematics``) from
    ``host:port``."""
    table, reading = result.table, result.reading
    version = reading.version if reading is not None else None
    joints = reading.joints if reading is not None and result.calibrated else None
    summary = {
        "host": host, "port": port, "connected": reading is not None,
        "model": table.model,
        "software_version": str(version) if version else None,
        "build_date": version.build_date if version else None,
        "calibrated": result.calibrated,
        "calibration_status": table.calibration_status,
        "calibration_status_text": table.status_text,
        "hash": table.sha256,
        "ur_calibration_hash": ur_calibration_hash(table),
        "checksums": list(table.checksums) if table.checksums is not None else None,
        "dh": table.as_dict(),
        "joints": joints.tolist() if joints is not None else None,
        "nominal_vs_calibrated": None,
        "nominal_vs_calibrated_workspace_max": _as_dict(result.nominal_difference),
        "calibrated_vs_controller": None,
        "saved_to": None,
        "robot_file_matches": None,
        "warnings": list(result.warnings),
    }
    if joints is not None:
        summary["nominal_vs_calibrated"] = _as_dict(
            fk_difference(table, nominal_table(table.model), joints))
        summary["calibrated_vs_controller"] = _as_dict(_controller_check(table, reading))
    return summary


def _controller_check(table, reading) -> FKDifference | None:
    """Calibrated FK (with the active TCP offset) against the TCP pose the controller reported
    in the same message: about zero when the table is this arm's."""
    if reading.tcp_pose is None or reading.tcp_offset is None:
        return None
    T = fk(table, reading.joints) @ T_from_ur_pose(reading.tcp_offset)
    lin, ang = pose_difference(T, T_from_ur_pose(reading.tcp_pose))
    return FKDifference(float(lin) * 1000.0, float(np.degrees(ang)))


def _as_dict(diff: FKDifference | None) -> dict | None:
    if diff is None:
        return None
    return {"translation_mm": diff.translation_mm, "rotation_deg": diff.rotation_deg}


def format_text(s: dict) -> str:
    """The human-readable report of a :func:`summarize` result."""
    where = f"{s['host']}, read-only port {s['port']}"
    if not s["connected"]:
        where += " (not reached)"
    software = (f"{s['software_version']} (built {s['build_date']})" if s["software_version"]
                else "unknown (no version message)")
    status = (f"{s['calibration_status']} ({s['calibration_status_text']}), read from the "
              f"controller" if s["calibrated"] else "NOT READ: nominal model shown")
    lines = [f"UR controller {where}", f"  software     {software}",
             f"  model        {s['model']}", f"  calibration  {status}",
             f"  hash         {s['hash']}", f"  ur hash      {s['ur_calibration_hash']}",
             "  DH table     joint      theta (rad)           a (m)           d (m)"
             "     alpha (rad)"]
    dh = s["dh"]
    for i in range(6):
        lines.append(f"               {i + 1:>5} {dh['theta'][i]:>16.10f} {dh['a'][i]:>15.10f} "
                     f"{dh['d'][i]:>15.9f} {dh['alpha'][i]:>15.10f}")
    if s["joints"] is not None:
        lines.append("  at the current joints (rad): "
                     + ", ".join(f"{v:.4f}" for v in s["joints"]))
        lines.append("    nominal vs calibrated FK     " + _text(s["nominal_vs_calibrated"]))
        if s["calibrated_vs_controller"] is not None:
            lines.append("    calibrated FK vs controller  "
                         + _text(s["calibrated_vs_controller"]))
    if s["nominal_vs_calibrated_workspace_max"] is not None:
        lines.append("  over the workspace, nominal FK is up to "
                     + _text(s["nominal_vs_calibrated_workspace_max"]) + " from calibrated")
    if s["saved_to"]:
        lines.append(f"  saved to     {s['saved_to']} (use it with --robot)")
    return "\n".join(lines)


def _text(d: dict) -> str:
    return f"{d['translation_mm']:.3f} mm, {d['rotation_deg']:.4f} deg"
