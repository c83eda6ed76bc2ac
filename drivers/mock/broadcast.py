"""The mock arm's primary-interface broadcast: what a UR controller sends on its read-only ports
(a version message, then ROBOT_STATE messages whose KINEMATICS_INFO holds the arm's DH table).

The mock arm does not open a network port. It writes one version message and one ROBOT_STATE
into one end of a local socket pair and reads the other end with
:func:`drivers.ur.primary.read_primary_stream`, the code that reads a real controller's stream
(splitting by sizes, decoding, the nominal fallback with warnings). So a mock arm's calibration
reaches the capture by exactly the path a UR arm's does. Layouts: :mod:`drivers.ur.primary_format`.
"""

from __future__ import annotations

import socket
import struct

import numpy as np

from armstereo.robot.dh import DHTable
from armstereo.transforms import ur_pose_from_T
from drivers.ur.primary_format import (
    JOINT,
    KINEMATICS,
    MESSAGE_HEADER,
    POSE,
    ROBOT_MESSAGE,
    ROBOT_MESSAGE_HEADER,
    ROBOT_STATE,
    SUB_CARTESIAN_INFO,
    SUB_HEADER,
    SUB_JOINT_DATA,
    SUB_KINEMATICS_INFO,
    VERSION_MESSAGE,
)

MOCK_SOFTWARE_VERSION = (5, 12, 0, 0)  # an e-Series controller
PROJECT_NAME = b"URControl"
BUILD_DATE = b"mock arm"
SOURCE_CONTROLLER = -2
JOINT_MODE_RUNNING = 253
UNKNOWN_CHECKSUM = 0xFFFFFFFF


def version_message(version: tuple[int, int, int, int] = MOCK_SOFTWARE_VERSION) -> bytes:
    """ROBOT_MESSAGE type 3 (version) as a controller sends it first on every connection."""
    major, minor, bugfix, build = version
    body = (ROBOT_MESSAGE_HEADER.pack(0, SOURCE_CONTROLLER, VERSION_MESSAGE)
            + struct.pack(">b", len(PROJECT_NAME)) + PROJECT_NAME
            + struct.pack(">BBii", major, minor, bugfix, build) + BUILD_DATE)
    return _message(ROBOT_MESSAGE, body)


def robot_state(table: DHTable, q: np.ndarray, T_base_flange: np.ndarray) -> bytes:
    """ROBOT_STATE with JOINT_DATA (``q``, rad), CARTESIAN_INFO (``T_base_flange`` as the TCP
    pose with a zero TCP offset, ``base`` frame) and KINEMATICS_INFO (``table``)."""
    joints = b"".join(JOINT.pack(v, v, 0.0, 0.0, 48.0, 30.0, 30.0, JOINT_MODE_RUNNING)
                      for v in np.asarray(q, dtype=float))
    cartesian = POSE.pack(*ur_pose_from_T(T_base_flange)) + POSE.pack(*([0.0] * 6))
    checksums = table.checksums if table.checksums is not None else (UNKNOWN_CHECKSUM,) * 6
    status = 0 if table.calibration_status is None else table.calibration_status
    kinematics = KINEMATICS.pack(*checksums, *table.theta, *table.a, *table.d, *table.alpha,
                                 status)
    body = (_sub(SUB_JOINT_DATA, joints) + _sub(SUB_CARTESIAN_INFO, cartesian)
            + _sub(SUB_KINEMATICS_INFO, kinematics))
    return _message(ROBOT_STATE, body)


def read_broadcast(table: DHTable, q: np.ndarray, T_base_flange: np.ndarray, *,
                   expected_model: str | None, name: str = "mock arm"):
    """What a capture reads from this broadcast: ``drivers.ur.primary.ArmKinematics`` (the
    table as decoded from the bytes, or the nominal one with warnings)."""
    from drivers.ur.primary import kinematics_from_reading, read_primary_stream

    data = version_message() + robot_state(table, q, T_base_flange)
    sender, receiver = socket.socketpair()
    try:
        sender.sendall(data)  # well below the socket buffer: never blocks
        sender.close()
        stream = receiver.makefile("rb", buffering=0)
        try:
            reading = read_primary_stream(stream, name, 0)
        finally:
            stream.close()
    finally:
        receiver.close()
    return kinematics_from_reading(reading, expected_model)


def _sub(kind: int, payload: bytes) -> bytes:
    return SUB_HEADER.pack(len(payload) + SUB_HEADER.size, kind) + payload


def _message(kind: int, body: bytes) -> bytes:
    return MESSAGE_HEADER.pack(len(body) + MESSAGE_HEADER.size, kind) + body
