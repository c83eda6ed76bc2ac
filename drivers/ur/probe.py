"""Check a UR controller's ports and RTDE handshake in Python, with timeouts.

ur_rtde's constructors connect without a timeout (an unreachable host blocks for the OS SYN
timeout, about two minutes) and then wait for the first data package forever, holding the GIL
all along, so nothing else in the process runs, not even Ctrl-C. Doing the same handshake here
first (protocol version, controller version, a one-variable output recipe, start, first data
package), each step with a deadline, turns those hangs into a ConnectionFailed naming the host
within seconds. The probe subscribes outputs only, so it reserves no input registers.

Wire format (UR's RTDE guide, protocol 2): every package is ``uint16 size`` (header included),
``uint8 type``, then a big-endian payload.
"""

from __future__ import annotations

import socket
import struct
import time
from dataclasses import dataclass

from armstereo.errors import ConnectionFailed

RTDE_PORT = 30004
DASHBOARD_PORT = 29999
SCRIPT_PORT = 30003

PROTOCOL_VERSION = 2
PROBE_FREQUENCY_HZ = 125.0  # allowed on every controller generation (CB3 tops out at 125 Hz)
PROBE_VARIABLE = "timestamp"

_HEADER = struct.Struct(">HB")
TYPE_PROTOCOL_VERSION = ord("V")
TYPE_CONTROLLER_VERSION = ord("v")
TYPE_SETUP_OUTPUTS = ord("O")
TYPE_START = ord("S")
TYPE_DATA = ord("U")


@dataclass(frozen=True)
class ControllerInfo:
    """What the handshake learned: the controller's software version (major, minor, bugfix,
    build). Major 3 = CB3, 5 = e-Series, 10+ = PolyScope X."""

    host: str
    version: tuple[int, int, int, int]

    @property
    def series(self) -> str:
        major = self.version[0]
        return "CB3" if major < 5 else ("e-Series" if major < 10 else "PolyScope X")

    @property
    def data_rate_hz(self) -> float:
        """RTDE rate ur_rtde picks with frequency=-1: 125 Hz on CB3, 500 Hz otherwise."""
        return 125.0 if self.version[0] < 5 else 500.0

    @property
    def uses_dashboard(self) -> bool:
        """ur_rtde's control interface opens the dashboard server on PolyScope < 10."""
        return self.version[0] < 10

    @property
    def accepts_script_upload(self) -> bool:
        """The script port takes ur_rtde's control script (PolyScope X only from 10.10)."""
        return self.version[0] < 10 or tuple(self.version[:2]) >= (10, 10)

    def __str__(self) -> str:
        return f"{self.series}, software {'.'.join(str(v) for v in self.version)}"


def check_controller(host: str, timeout: float) -> ControllerInfo:
    """RTDE handshake on port 30004, then reachability of the ports ur_rtde's control interface
    opens next (dashboard 29999, script 30003). Raises ConnectionFailed naming host and port."""
    info = rtde_handshake(host, timeout)
    if info.uses_dashboard:
        check_port(host, DASHBOARD_PORT, timeout, "dashboard server")
    if not info.accepts_script_upload:
        raise ConnectionFailed(
            f"UR controller at {host} ({info}) cannot take ur_rtde's control script: "
            f"PolyScope X needs 10.10 or newer")
    check_port(host, SCRIPT_PORT, timeout, "script port")
    return info


def check_port(host: str, port: int, timeout: float, what: str) -> None:
    """Open and close a TCP connection to ``host:port`` within ``timeout`` seconds."""
    try:
        socket.create_connection((host, port), timeout=timeout).close()
    except OSError as err:
        raise ConnectionFailed(_unreachable(host, port, f"{what}: {_reason(err)}")) from err


def rtde_handshake(host: str, timeout: float) -> ControllerInfo:
    """Connect to RTDE, negotiate protocol 2, read the controller version, start a one-variable
    output recipe and wait for its first data package; ``timeout`` seconds for the TCP connect
    and again for the rest. Raises ConnectionFailed."""
    try:
        sock = socket.create_connection((host, RTDE_PORT), timeout=timeout)
    except socket.gaierror as err:
        raise ConnectionFailed(f"cannot resolve UR controller host {host!r}: {err}") from err
    except OSError as err:
        raise ConnectionFailed(_unreachable(host, RTDE_PORT, _reason(err))) from err
    with sock:
        link = _Link(sock, host, time.monotonic() + timeout, timeout)
        accepted = link.request(TYPE_PROTOCOL_VERSION, struct.pack(">H", PROTOCOL_VERSION),
                                "answer to the protocol version request")
        if not accepted or not accepted[0]:
            raise ConnectionFailed(f"UR controller at {host}:{RTDE_PORT} refused RTDE protocol "
                                   f"{PROTOCOL_VERSION} (PolyScope older than 3.5?)")
        body = link.request(TYPE_CONTROLLER_VERSION, b"", "controller version")
        if len(body) < 16:
            raise ConnectionFailed(f"UR controller at {host}:{RTDE_PORT} sent a malformed "
                                   f"controller version ({len(body)} bytes, expected 16)")
        version = struct.unpack(">IIII", body[:16])
        # Same payload layout as ur_rtde: frequency, then names each followed by a comma.
        body = link.request(TYPE_SETUP_OUTPUTS,
                            struct.pack(">d", PROBE_FREQUENCY_HZ) + f"{PROBE_VARIABLE},".encode(),
                            "answer to the output setup")
        types = body[1:].decode("ascii", "replace")
        if not body or "NOT_FOUND" in types:
            raise ConnectionFailed(f"UR controller at {host}:{RTDE_PORT} does not provide the "
                                   f"RTDE output {PROBE_VARIABLE!r} (answer {types!r})")
        started = link.request(TYPE_START, b"", "answer to the start request")
        if not started or not started[0]:
            raise ConnectionFailed(f"UR controller at {host}:{RTDE_PORT} refused to start "
                                   f"RTDE data streaming")
        link.receive(TYPE_DATA, "first data package")
    return ControllerInfo(host, tuple(int(v) for v in version))


class _Link:
    """Package I/O on the probe socket against one deadline."""

    def __init__(self, sock: socket.socket, host: str, deadline: float, timeout: float):
        self.sock, self.host, self.deadline, self.timeout = sock, host, deadline, timeout

    def request(self, kind: int, payload: bytes, step: str) -> bytes:
        try:
            self.sock.sendall(_HEADER.pack(_HEADER.size + len(payload), kind) + payload)
        except OSError as err:
            raise ConnectionFailed(
                f"UR controller at {self.host}:{RTDE_PORT} dropped the connection before the "
                f"{step} ({_reason(err)})") from err
        return self.receive(kind, step)

    def receive(self, kind: int, step: str) -> bytes:
        """Body of the next package of type ``kind``; text messages and others are skipped."""
        while True:
            size, got = _HEADER.unpack(self._read(_HEADER.size, step))
            if size < _HEADER.size:
                raise ConnectionFailed(f"UR controller at {self.host}:{RTDE_PORT} sent a "
                                       f"malformed RTDE package instead of the {step}")
            body = self._read(size - _HEADER.size, step)
            if got == kind:
                return body

    def _read(self, n: int, step: str) -> bytes:
        data = b""
        while len(data) < n:
            left = self.deadline - time.monotonic()
            if left <= 0:
                raise ConnectionFailed(
                    f"UR controller at {self.host}:{RTDE_PORT} accepted the connection but gave "
                    f"no {step} within {self.timeout:g} s: is it an RTDE server, and is the "
                    f"controller booted?")
            self.sock.settimeout(left)
            try:
                chunk = self.sock.recv(n - len(data))
            except TimeoutError:
                continue
            except OSError as err:
                raise ConnectionFailed(
                    f"UR controller at {self.host}:{RTDE_PORT} dropped the connection waiting "
                    f"for the {step} ({_reason(err)})") from err
            if not chunk:
                raise ConnectionFailed(f"UR controller at {self.host}:{RTDE_PORT} closed the "
                                       f"connection waiting for the {step}")
            data += chunk
        return data


def _unreachable(host: str, port: int, reason: str) -> str:
    return (f"cannot reach UR controller at {host}:{port} ({reason}): check the IP and that "
            f"the robot is on")


def _reason(err: OSError) -> str:
    if isinstance(err, TimeoutError):
        return "no answer"
    return err.strerror or str(err) or type(err).__name__
