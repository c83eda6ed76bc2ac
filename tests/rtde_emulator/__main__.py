"""Run one emulated UR controller: ``python -m tests.rtde_emulator --host 127.0.0.7``.

Control channel: JSON lines on stdin, one JSON reply line each on stdout. The first line
printed is ``{"ready": true, ...}`` once the ports listen, or ``{"ready": false,
"error": ...}`` (then the exit status is 3, e.g. the address is taken). Requests:

- ``{"op": "fault", "kind": "protective_stop"|"disconnect"|"stall", "move": N, "at": 0.5}``
- ``{"op": "set", "start_delay_s": 3.0, "unlock_delay_s": 1.0, "remote_control": false}``
- ``{"op": "events"}`` (everything the controller received and did), ``{"op": "state"}``
- ``{"op": "teleport", "q": [6 rad]}``: put the resting arm at ``q`` (for kinematics tests)
- ``{"op": "quit"}``; end of stdin also ends the emulator.
"""

from __future__ import annotations

import argparse
import json
import logging
import sys

import numpy as np

from armstereo.robot.arm_model import ArmModel, ready_configuration
from armstereo.robot.dh import DHTable, nominal_table
from armstereo.robot.synthetic import synthetic_calibration

from . import DEFAULT_KINEMATICS
from .controller import Controller
from .faults import MoveFault, Settings
from .primary_server import start_primary
from .servers import start_servers

DEFAULT_VERSION = "5.12.0.1101534"  # e-Series: 500 Hz, serial number and remote-control check


def _parse(argv: list[str] | None) -> argparse.Namespace:
    p = argparse.ArgumentParser(prog="rtde_emulator", description=__doc__.splitlines()[0])
    p.add_argument("--host", required=True, help="loopback address to serve, e.g. 127.0.0.7")
    p.add_argument("--robot", default="ur5e", help="robot model (robot_models/)")
    p.add_argument("--q0", default=None, help="initial joints, JSON list (rad)")
    p.add_argument("--version", default=DEFAULT_VERSION, help="controller software version")
    p.add_argument("--settings", default="{}", help="initial settings, JSON object")
    p.add_argument("--kinematics", default=DEFAULT_KINEMATICS,
                   help="the arm's true kinematics: 'nominal' (exact nominal DH, broadcast as "
                        "URSim does) or 'calibrated:SEED' (a seeded factory calibration; "
                        f"default {DEFAULT_KINEMATICS})")
    return p.parse_args(argv)


def _kinematics(robot: str, spec: str) -> tuple[ArmModel, DHTable]:
    """The controller's model (its motion and reported poses) and the table it broadcasts."""
    if spec == "nominal":
        return ArmModel.load(robot), nominal_table(robot)
    kind, _, seed = spec.partition(":")
    if kind != "calibrated" or not seed.isdigit():
        raise SystemExit(f"--kinematics must be 'nominal' or 'calibrated:SEED', got {spec!r}")
    table = synthetic_calibration(robot, int(seed))
    return ArmModel.from_dh(table), table


def _reply(obj: dict) -> None:
    sys.stdout.write(json.dumps(obj) + "\n")
    sys.stdout.flush()


def _request(line: str, controller: Controller) -> tuple[dict, bool]:
    """Answer one control request; (reply, keep running)."""
    try:
        req = json.loads(line)
        op = req.pop("op")
        with controller.lock:
            if op == "fault":
                fault = MoveFault(**req)
                controller.faults.append(fault)
                controller.log("fault_armed", fault=fault.kind, move=fault.move, at=fault.at)
                return {"ok": True}, True
            if op == "set":
                controller.settings.update(req)
                return {"ok": True}, True
            if op == "events":
                return {"ok": True, "events": list(controller.events)}, True
            if op == "state":
                return {"ok": True, "state": controller.state()}, True
            if op == "teleport":
                if controller.motion is not None:
                    return {"ok": False, "error": "the arm is moving"}, True
                controller.q = np.array(req["q"], dtype=float).reshape(6)
                return {"ok": True}, True
        if op == "quit":
            return {"ok": True}, False
        return {"ok": False, "error": f"unknown op {op!r}"}, True
    except (ValueError, KeyError, TypeError) as err:
        return {"ok": False, "error": f"{type(err).__name__}: {err}"}, True


def main(argv: list[str] | None = None) -> int:
    args = _parse(argv)
    logging.basicConfig(level=logging.WARNING, stream=sys.stderr)
    model, table = _kinematics(args.robot, args.kinematics)
    q0 = np.array(json.loads(args.q0)) if args.q0 else ready_configuration(model.name)
    version = tuple(int(v) for v in args.version.split("."))
    settings = Settings()
    settings.update(json.loads(args.settings))
    controller = Controller(model, q0, version, settings)
    try:
        network, clock = start_servers(args.host, controller)
        start_primary(network, controller, table)
    except OSError as err:
        _reply({"ready": False, "error": f"{args.host}: {err}"})
        return 3
    _reply({"ready": True, "host": args.host, "version": args.version,
            "rate_hz": controller.rate_hz})
    for line in sys.stdin:
        if not line.strip():
            continue
        answer, keep = _request(line, controller)
        _reply(answer)
        if not keep:
            break
    clock.running = False
    network.drop()
    return 0


if __name__ == "__main__":
    sys.exit(main())
