"""Byte layout of a UR controller's primary/secondary client interface, decoding only.

Everything is big-endian. A message is ``int32 size`` (the whole message, these 5 header bytes
included), ``uint8 type``, then ``size - 5`` bytes of body. Types used here: 16 ROBOT_STATE and
20 ROBOT_MESSAGE; all others are skipped by their size.

A ROBOT_STATE body is a run of sub-packages, each ``int32 size`` (its own 5 header bytes
included), ``uint8 type``, payload. Their number, order and sizes differ between software
versions (and a controller may leave some out), so they are walked by their sizes and unknown
types skipped. Sub-types read here:

- 1 JOINT_DATA: 6 x (q_actual, q_target, qd_actual: double; current, voltage, motor and
  micro temperature: float; mode: uint8) = 6 x 41 bytes.
- 4 CARTESIAN_INFO: TCP pose x, y, z, rx, ry, rz (m, rotation vector, ``base`` frame), then (on
  software >= 3.2) the active TCP offset as six more doubles.
- 5 KINEMATICS_INFO: checksum[6] uint32, theta[6], a[6], d[6], alpha[6] double, then
  calibration_status uint32 = 220 bytes of payload. A longer payload (a newer controller
  appending fields) is read up to 220 bytes; a shorter one is not a table and is skipped.

A ROBOT_MESSAGE body starts with ``uint64 timestamp, int8 source, uint8 message type``; type 3
is the version message: ``int8 n, char[n] project name, uint8 major, uint8 minor, int32 bugfix,
int32 build, char[] build date`` (the rest of the message).
"""

from __future__ import annotations

import struct
from dataclasses import dataclass, field

import numpy as np

MESSAGE_HEADER = struct.Struct(">iB")
SUB_HEADER = struct.Struct(">iB")
ROBOT_STATE = 16
ROBOT_MESSAGE = 20
SUB_JOINT_DATA = 1
SUB_CARTESIAN_INFO = 4
SUB_KINEMATICS_INFO = 5
VERSION_MESSAGE = 3
# Largest message accepted: a ROBOT_STATE is about 1.4 kB today; a size beyond this means the
# stream is out of step (or not a UR controller), not a big message.
MAX_MESSAGE_BYTES = 1 << 20

KINEMATICS = struct.Struct(">6I24dI")
JOINT = struct.Struct(">3d4fB")
POSE = struct.Struct(">6d")
ROBOT_MESSAGE_HEADER = struct.Struct(">QbB")
_VERSION_NUMBERS = struct.Struct(">BBii")


@dataclass(frozen=True)
class KinematicsInfo:
    """The controller's DH table (rad, m) with per-joint checksums and calibration status;
    ``extra_bytes``: payload bytes beyond the 220 known ones (ignored)."""

    checksums: tuple[int, ...]
    theta: tuple[float, ...]
    a: tuple[float, ...]
    d: tuple[float, ...]
    alpha: tuple[float, ...]
    calibration_status: int
    extra_bytes: int = 0


@dataclass(frozen=True)
class VersionInfo:
    """The controller software's version message."""

    project: str
    major: int
    minor: int
    bugfix: int
    build: int
    build_date: str

    def __str__(self) -> str:
        return f"{self.major}.{self.minor}.{self.bugfix}.{self.build}"


@dataclass
class RobotState:
    """What one ROBOT_STATE message held. ``valid`` is False when its sub-package sizes do not
    tile the message (then nothing of it is used); ``notes`` say what was skipped and why."""

    valid: bool = True
    subpackages: list[tuple[int, int]] = field(default_factory=list)  # (type, size) in order
    kinematics: KinematicsInfo | None = None
    joints: np.ndarray | None = None       # actual joints (6,) rad
    tcp_pose: np.ndarray | None = None     # UR pose (6,) in base: m, rotation vector
    tcp_offset: np.ndarray | None = None   # UR pose (6,) of the TCP in the flange frame
    short_kinematics: int = 0              # KINEMATICS_INFO sub-packages too short for a table
    notes: list[str] = field(default_factory=list)


class MessageSplitter:
    """Cuts a byte stream into messages by their sizes. Feed it what the socket gives (any
    split); it returns complete ``(type, body)`` pairs. After a size that cannot be right it
    stops for good and sets ``error`` (the stream is out of step and cannot be trusted)."""

    def __init__(self) -> None:
        self._buffer = bytearray()
        self.error: str | None = None

    @property
    def pending(self) -> tuple[int, int | None]:
        """(bytes held of an incomplete message, its declared size or None if unknown yet)."""
        if len(self._buffer) >= MESSAGE_HEADER.size:
            return len(self._buffer), MESSAGE_HEADER.unpack_from(self._buffer)[0]
        return len(self._buffer), None

    def feed(self, data: bytes) -> list[tuple[int, bytes]]:
        if self.error is not None:
            return []
        self._buffer += data
        out = []
        while len(self._buffer) >= MESSAGE_HEADER.size:
            size, kind = MESSAGE_HEADER.unpack_from(self._buffer)
            if not MESSAGE_HEADER.size <= size <= MAX_MESSAGE_BYTES:
                self.error = (f"a message declares {size} bytes (allowed "
                              f"{MESSAGE_HEADER.size}..{MAX_MESSAGE_BYTES}): stream out of step")
                self._buffer.clear()
                break
            if len(self._buffer) < size:
                break
            out.append((kind, bytes(self._buffer[MESSAGE_HEADER.size:size])))
            del self._buffer[:size]
        return out


def parse_robot_state(body: bytes) -> RobotState:
    """Decode the sub-packages of a ROBOT_STATE body (after the 5-byte message header)."""
    state = RobotState()
    offset = 0
    while offset < len(body):
        left = len(body) - offset
        if left < SUB_HEADER.size:
            return _invalid(state, f"{left} stray bytes after the last sub-package")
        size, kind = SUB_HEADER.unpack_from(body, offset)
        if not SUB_HEADER.size <= size <= left:
            return _invalid(state, f"sub-package type {kind} at byte {offset} declares {size} "
                                   f"bytes, {left} left in the message")
        state.subpackages.append((kind, size))
        _decode_subpackage(state, kind, body[offset + SUB_HEADER.size:offset + size])
        offset += size
    return state


def _invalid(state: RobotState, why: str) -> RobotState:
    return RobotState(valid=False, subpackages=state.subpackages,
                      notes=state.notes + [f"malformed ROBOT_STATE ignored: {why}"])


def _decode_subpackage(state: RobotState, kind: int, payload: bytes) -> None:
    if kind == SUB_KINEMATICS_INFO:
        if len(payload) < KINEMATICS.size:
            state.short_kinematics += 1
            state.notes.append(f"KINEMATICS_INFO of {len(payload)} payload bytes (not a table, "
                               f"{KINEMATICS.size} expected) skipped")
            return
        v = KINEMATICS.unpack_from(payload)
        state.kinematics = KinematicsInfo(checksums=v[0:6], theta=v[6:12], a=v[12:18],
                                          d=v[18:24], alpha=v[24:30], calibration_status=v[30],
                                          extra_bytes=len(payload) - KINEMATICS.size)
    elif kind == SUB_JOINT_DATA and len(payload) >= 6 * JOINT.size:
        state.joints = np.array([JOINT.unpack_from(payload, i * JOINT.size)[0]
                                 for i in range(6)])
    elif kind == SUB_CARTESIAN_INFO and len(payload) >= POSE.size:
        state.tcp_pose = np.array(POSE.unpack_from(payload))
        if len(payload) >= 2 * POSE.size:
            state.tcp_offset = np.array(POSE.unpack_from(payload, POSE.size))


def parse_version_message(body: bytes) -> VersionInfo | None:
    """The version of a ROBOT_MESSAGE body, or None if it is another kind of robot message.
    Raises ValueError if it is a version message that does not fit its layout."""
    if len(body) < ROBOT_MESSAGE_HEADER.size:
        raise ValueError(f"robot message of {len(body)} bytes is shorter than its header")
    _, _, kind = ROBOT_MESSAGE_HEADER.unpack_from(body)
    if kind != VERSION_MESSAGE:
        return None
    payload = body[ROBOT_MESSAGE_HEADER.size:]
    n = struct.unpack_from(">b", payload)[0] if payload else -1
    end = 1 + n + _VERSION_NUMBERS.size
    if n < 0 or len(payload) < end:
        raise ValueError(f"version message of {len(payload)} payload bytes does not fit its "
                         f"layout (project name of {n} bytes)")
    major, minor, bugfix, build = _VERSION_NUMBERS.unpack_from(payload, 1 + n)
    return VersionInfo(project=payload[1:1 + n].decode("ascii", "replace"), major=major,
                       minor=minor, bugfix=bugfix, build=build,
                       build_date=payload[end:].decode("ascii", "replace"))
