"""The emulated controller's primary/secondary client interface: a state stream, never a command
channel.

Served on the read-only ports 30011 and 30012 and also on 30001/30002 (where a real controller
would run any bytes received as URScript): every connection and every byte received is logged
(events ``primary_connect`` and ``primary_received``), so a test can prove that a client never
touched 30001/30002 and never wrote a byte anywhere. Received bytes are otherwise ignored.

On connect: a version message (ROBOT_MESSAGE type 20, message type 3) with the controller's
version, then every 100 ms a ROBOT_STATE (type 16) with the sub-packages and sizes a UR5e on
URSim 5.8 sends, in its order: ROBOT_MODE_DATA, JOINT_DATA (the actual joints), CARTESIAN_INFO
(the TCP pose in ``base`` and the TCP offset), KINEMATICS_INFO (the controller's DH table), then
opaque sub-packages of the right sizes. The encoding is written here from the published layout,
independently of the client's decoder.

Stream faults (setting ``primary_fault``): ``no_kinematics`` (states without KINEMATICS_INFO),
``short_kinematics`` (a 9-byte KINEMATICS_INFO, status only), ``resized`` (unknown sub-packages,
a longer ROBOT_MODE_DATA and 10 extra bytes at the end of KINEMATICS_INFO, as a newer software
version might send), ``truncate`` (the first state is cut after half its bytes, then the
connection closes), ``silent`` (connect, then nothing).
"""

from __future__ import annotations

import select
import socket
import struct
import time

from armstereo.robot.dh import DHTable
from armstereo.transforms import ur_pose_from_T

from .controller import Controller
from .servers import Network

PRIMARY_PORTS = (30001, 30002, 30011, 30012)
STATE_PERIOD_S = 0.1  # 10 Hz, as UR documents
PROJECT_NAME = b"URControl"
BUILD_DATE = b"01-01-2026, 00:00:00"
SOURCE_CONTROLLER = -2
ROBOT_STATE, ROBOT_MESSAGE, VERSION_MESSAGE = 16, 20, 3
JOINT_DATA, CARTESIAN_INFO, KINEMATICS_INFO = 1, 4, 5
JOINT_MODE_RUNNING = 253
MOTOR_TEMPERATURE_C = 30.0
# (sub-type, total size) of the sub-packages sent as zeros, around the modelled ones (URSim 5.8).
ROBOT_MODE = (0, 47)
OPAQUE_AFTER = ((9, 53), (3, 75), (2, 37), (6, 445), (7, 61), (8, 9), (10, 43), (11, 26), (12, 8))
FAULTS = ("", "no_kinematics", "short_kinematics", "resized", "truncate", "silent")
RESIZED_EXTRA = 10  # bytes appended to KINEMATICS_INFO by the "resized" fault
UNKNOWN_SUBTYPE = 99


def start_primary(network: Network, controller: Controller, table: DHTable) -> None:
    """Serve the primary stream of ``controller``, broadcasting ``table`` as its kinematics."""
    for port in PRIMARY_PORTS:
        network.listen(port, lambda sock, port=port: _session(sock, port, controller, table))


def _session(sock: socket.socket, port: int, c: Controller, table: DHTable) -> None:
    with c.lock:
        c.log("primary_connect", port=port)
        fault = c.settings.primary_fault
    try:
        if fault != "silent":
            sock.sendall(version_message(c.version))
        first = True
        while True:
            if fault != "silent":
                with c.lock:
                    message = robot_state(c, table, fault)
                if fault == "truncate" and first:
                    sock.sendall(message[:len(message) // 2])
                    return
                sock.sendall(message)
            first = False
            if not _drain(sock, port, c, time.monotonic() + STATE_PERIOD_S):
                return
    except OSError:
        return


def _drain(sock: socket.socket, port: int, c: Controller, until: float) -> bool:
    """Wait until ``until`` while logging whatever the client sends; False once it is gone."""
    while (left := until - time.monotonic()) > 0:
        ready, _, _ = select.select([sock], [], [], left)
        if not ready:
            continue
        data = sock.recv(4096)
        if not data:
            return False
        with c.lock:
            c.log("primary_received", port=port, bytes=len(data))
    return True


def version_message(version: tuple[int, ...]) -> bytes:
    """ROBOT_MESSAGE / version: timestamp, source, type 3, then name, major, minor, bugfix,
    build and the build date."""
    major, minor, bugfix, build = (list(version) + [0, 0, 0, 0])[:4]
    body = (struct.pack(">QbB", 0, SOURCE_CONTROLLER, VERSION_MESSAGE)
            + struct.pack(">b", len(PROJECT_NAME)) + PROJECT_NAME
            + struct.pack(">BBii", major, minor, bugfix, build) + BUILD_DATE)
    return _message(ROBOT_MESSAGE, body)


def robot_state(c: Controller, table: DHTable, fault: str = "") -> bytes:
    """One ROBOT_STATE message of the controller's current state (call under ``c.lock``)."""
    mode_type, mode_size = ROBOT_MODE
    subs = [_opaque(mode_type, mode_size + (13 if fault == "resized" else 0)),
            _sub(JOINT_DATA, _joint_data(c)),
            _sub(CARTESIAN_INFO, struct.pack(">12d", *c.tcp_pose(),
                                             *ur_pose_from_T(c.T_flange_tcp)))]
    if fault == "resized":
        subs.append(_opaque(UNKNOWN_SUBTYPE, 20))
    if fault == "short_kinematics":
        subs.append(_sub(KINEMATICS_INFO, struct.pack(">I", _status(table))))
    elif fault != "no_kinematics":
        extra = b"\xaa" * RESIZED_EXTRA if fault == "resized" else b""
        subs.append(_sub(KINEMATICS_INFO, kinematics_payload(table) + extra))
    subs += [_opaque(kind, size) for kind, size in OPAQUE_AFTER]
    if fault == "resized":
        subs.append(_opaque(UNKNOWN_SUBTYPE + 1, 33))
    return _message(ROBOT_STATE, b"".join(subs))


def kinematics_payload(table: DHTable) -> bytes:
    """KINEMATICS_INFO payload: checksums, theta, a, d, alpha (all six each), status."""
    checksums = table.checksums if table.checksums is not None else (0xFFFFFFFF,) * 6
    return struct.pack(">6I24dI", *checksums, *table.theta, *table.a, *table.d, *table.alpha,
                       _status(table))


def _status(table: DHTable) -> int:
    return 0 if table.calibration_status is None else table.calibration_status


def _joint_data(c: Controller) -> bytes:
    return b"".join(struct.pack(">3d4fB", q, q, qd, 0.0, 48.0, MOTOR_TEMPERATURE_C,
                                MOTOR_TEMPERATURE_C, JOINT_MODE_RUNNING)
                    for q, qd in zip(c.q, c.qd, strict=True))


def _sub(kind: int, payload: bytes) -> bytes:
    return struct.pack(">iB", len(payload) + 5, kind) + payload


def _opaque(kind: int, size: int) -> bytes:
    return _sub(kind, bytes(size - 5))


def _message(kind: int, body: bytes) -> bytes:
    return struct.pack(">iB", len(body) + 5, kind) + body
