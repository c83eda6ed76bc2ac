"""RTDE wire format (protocol version 2) as a UR controller speaks it on port 30004.

Every package is ``uint16 size`` (3-byte header included), ``uint8 type``, then a big-endian
payload. The tables below give the RTDE type of each field this emulator serves; the names and
types are UR's (RTDE guide), and ur_rtde parses output packages with the same sizes.
"""

from __future__ import annotations

import socket
import struct

HEADER = struct.Struct(">HB")

REQUEST_PROTOCOL_VERSION = ord("V")
GET_URCONTROL_VERSION = ord("v")
TEXT_MESSAGE = ord("M")
DATA_PACKAGE = ord("U")
SETUP_OUTPUTS = ord("O")
SETUP_INPUTS = ord("I")
START = ord("S")
PAUSE = ord("P")

# RTDE type name -> struct format of one value.
TYPE_FORMATS = {
    "BOOL": "?", "UINT8": "B", "UINT32": "I", "UINT64": "Q", "INT32": "i", "DOUBLE": "d",
    "VECTOR3D": "3d", "VECTOR6D": "6d", "VECTOR6INT32": "6i", "VECTOR6UINT32": "6I",
}

_OUTPUTS = {
    "DOUBLE": ("timestamp", "actual_execution_time", "speed_scaling", "target_speed_fraction",
               "actual_momentum", "actual_main_voltage", "actual_robot_voltage",
               "actual_robot_current", "standard_analog_input0", "standard_analog_input1",
               "standard_analog_output0", "standard_analog_output1", "payload"),
    "VECTOR6D": ("target_q", "target_qd", "target_qdd", "target_current", "target_moment",
                 "actual_q", "actual_qd", "actual_current", "joint_control_output",
                 "actual_TCP_pose", "actual_TCP_speed", "actual_TCP_force", "target_TCP_pose",
                 "target_TCP_speed", "joint_temperatures", "actual_joint_voltage",
                 "ft_raw_wrench", "payload_inertia", "actual_current_as_torque"),
    "VECTOR3D": ("actual_tool_accelerometer", "payload_cog"),
    "INT32": ("robot_mode", "safety_mode"),
    "VECTOR6INT32": ("joint_mode",),
    "UINT32": ("runtime_state", "robot_status_bits", "safety_status_bits"),
    "UINT64": ("actual_digital_input_bits", "actual_digital_output_bits"),
}
OUTPUT_TYPES: dict[str, str] = {name: kind for kind, names in _OUTPUTS.items()
                                for name in names}
OUTPUT_TYPES.update({f"output_int_register_{i}": "INT32" for i in range(48)})
OUTPUT_TYPES.update({f"output_double_register_{i}": "DOUBLE" for i in range(48)})

INPUT_TYPES: dict[str, str] = {
    "external_force_torque": "VECTOR6D", "speed_slider_mask": "UINT32",
    "speed_slider_fraction": "DOUBLE", "standard_digital_output_mask": "UINT8",
    "standard_digital_output": "UINT8", "configurable_digital_output_mask": "UINT8",
    "configurable_digital_output": "UINT8", "tool_digital_output_mask": "UINT8",
    "tool_digital_output": "UINT8", "standard_analog_output_mask": "UINT8",
    "standard_analog_output_type": "UINT8", "standard_analog_output_0": "DOUBLE",
    "standard_analog_output_1": "DOUBLE",
}
INPUT_TYPES.update({f"input_int_register_{i}": "INT32" for i in range(48)})
INPUT_TYPES.update({f"input_double_register_{i}": "DOUBLE" for i in range(48)})


def width(rtde_type: str) -> int:
    """Number of scalars in one value of ``rtde_type`` (6 for VECTOR6D)."""
    fmt = TYPE_FORMATS[rtde_type]
    return int(fmt[:-1]) if len(fmt) > 1 else 1


def pack(kind: int, payload: bytes = b"") -> bytes:
    """One package of type ``kind``."""
    return HEADER.pack(HEADER.size + len(payload), kind) + payload


def recipe_struct(types: list[str]) -> struct.Struct:
    """Big-endian struct for a recipe id byte followed by fields of ``types``."""
    return struct.Struct(">B" + "".join(TYPE_FORMATS[t] for t in types))


def names_of(payload: bytes) -> list[str]:
    """Variable names of a setup request: ``"a,b,c,"`` (ur_rtde adds a trailing comma)."""
    return [n for n in payload.decode("ascii", "replace").split(",") if n]


def flatten(values: list) -> list:
    """Recipe values (scalars and vectors) as one flat list for ``struct.pack``."""
    flat: list = []
    for v in values:
        if isinstance(v, (list, tuple)):
            flat.extend(v)
        else:
            flat.append(v)
    return flat


class PackageReader:
    """Reads whole packages from a blocking socket; ``None`` at end of stream."""

    def __init__(self, sock: socket.socket):
        self.sock = sock
        self.buffer = b""

    def read(self) -> tuple[int, bytes] | None:
        header = self._exactly(HEADER.size)
        if header is None:
            return None
        size, kind = HEADER.unpack(header)
        body = self._exactly(max(0, size - HEADER.size))
        return None if body is None else (kind, body)

    def _exactly(self, n: int) -> bytes | None:
        while len(self.buffer) < n:
            try:
                chunk = self.sock.recv(65536)
            except OSError:
                return None
            if not chunk:
                return None
            self.buffer += chunk
        data, self.buffer = self.buffer[:n], self.buffer[n:]
        return data
