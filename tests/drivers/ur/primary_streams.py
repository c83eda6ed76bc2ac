"""Byte streams for the primary-interface tests: the published captures (tests/data/ur_primary)
and variants of them built by walking and re-assembling their sub-packages."""

from __future__ import annotations

import struct
from pathlib import Path

DATA = Path(__file__).resolve().parents[2] / "data" / "ur_primary"
ROBOT_STATE = (DATA / "ursim_5.8_ur5e_robot_state.bin").read_bytes()
VERSION_MESSAGE = (DATA / "urcontrol_5.24_version_message.bin").read_bytes()
KINEMATICS_INFO = 5


def subpackages(message: bytes = ROBOT_STATE) -> list[tuple[int, bytes]]:
    """(type, payload) of every sub-package of a ROBOT_STATE message, in order."""
    out, offset = [], 5
    while offset < len(message):
        size, kind = struct.unpack_from(">iB", message, offset)
        out.append((kind, message[offset + 5:offset + size]))
        offset += size
    return out


def robot_state(parts: list[tuple[int, bytes]]) -> bytes:
    """A ROBOT_STATE message of the given (type, payload) sub-packages."""
    body = b"".join(struct.pack(">iB", len(p) + 5, k) + p for k, p in parts)
    return struct.pack(">iB", len(body) + 5, 16) + body


def replaced(kind: int, payload: bytes | None) -> bytes:
    """The captured state with sub-package ``kind`` given a new payload (None: left out)."""
    return robot_state([(k, payload if k == kind else p) for k, p in subpackages()
                        if k != kind or payload is not None])


def kinematics_payload() -> bytes:
    return dict(subpackages())[KINEMATICS_INFO]
