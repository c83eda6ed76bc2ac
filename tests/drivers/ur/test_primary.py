"""The read-only primary client (drivers.ur.primary) against a scripted controller on a loopback
address: it reads the table, never sends a byte, never touches ports 30001/30002, and every
stream problem ends in the nominal model plus a warning instead of an exception."""

from __future__ import annotations

import itertools
import os
import socket
import threading
import time

import pytest

from armstereo.errors import ConfigError, ConnectionFailed
from armstereo.robot.dh import nominal_table
from drivers.ur import primary
from drivers.ur.primary import read_arm_kinematics, read_primary
from tests.drivers.ur.primary_streams import (
    KINEMATICS_INFO,
    ROBOT_STATE,
    VERSION_MESSAGE,
    kinematics_payload,
    replaced,
    robot_state,
    subpackages,
)

FAST_S = 1.0  # a clear answer without waiting for the timeout
_SENDALL = socket.socket.sendall  # the server's own, kept when a test forbids sending
_addresses = itertools.count()


class ScriptedController:
    """Serves one connection on ``host:port``: sends ``script`` = [(bytes, pause_s)], then
    closes (``close=True``) or idles until the client leaves. Counts connections and the
    bytes it received."""

    def __init__(self, script: list[tuple[bytes, float]], *, port: int = 30012,
                 close: bool = False):
        self.script, self.close_after = script, close
        self.connections, self.received = 0, 0
        self.stopped = False
        self.listener, self.host = _bind(port)
        self.listener.settimeout(0.05)  # close() does not wake accept(): poll instead
        self.thread = threading.Thread(target=self._serve, daemon=True)
        self.thread.start()

    def _serve(self) -> None:
        while not self.stopped:
            try:
                conn, _ = self.listener.accept()
                break
            except TimeoutError:
                continue
            except OSError:
                return
        else:
            return
        self.connections += 1
        conn.settimeout(0.05)
        with conn:
            for data, pause in self.script:
                try:
                    _SENDALL(conn, data)
                except OSError:
                    return
                self._listen(conn, time.monotonic() + pause)
            if not self.close_after:
                self._listen(conn, time.monotonic() + 10.0)

    def _listen(self, conn: socket.socket, until: float) -> None:
        while time.monotonic() < until and not self.stopped:
            try:
                data = conn.recv(4096)
            except TimeoutError:
                continue
            except OSError:
                return
            if not data:
                return
            self.received += len(data)

    def stop(self) -> None:
        self.stopped = True
        self.thread.join(2.0)
        self.listener.close()


def _bind(port: int) -> tuple[socket.socket, str]:
    """A listener on a fresh 127.x.y.z (x from the process id: parallel runs do not meet)."""
    x = 16 + os.getpid() % 224
    for n in _addresses:
        host = f"127.{x}.{200 + n // 250 % 50}.{n % 250 + 2}"
        sock = socket.socket()
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            sock.bind((host, port))
        except OSError:
            sock.close()
            continue
        sock.listen(1)
        return sock, host
    raise AssertionError("unreachable")


@pytest.fixture
def serve():
    started: list[ScriptedController] = []

    def start(script, **kwargs) -> ScriptedController:
        server = ScriptedController(script, **kwargs)
        started.append(server)
        return server

    yield start
    for server in started:
        server.stop()


def chunks(data: bytes, size: int) -> list[tuple[bytes, float]]:
    return [(data[i:i + size], 0.0) for i in range(0, len(data), size)]


def test_reads_the_captured_stream_in_small_pieces_and_sends_nothing(serve):
    server = serve(chunks(VERSION_MESSAGE + ROBOT_STATE, 7))
    reading = read_primary(server.host)
    assert reading.kinematics.a == (0, -0.425, -0.3922, 0, 0, 0)
    assert str(reading.version) == "5.24.0.0" and reading.messages == 2
    assert reading.joints is not None and reading.tcp_pose is not None
    assert reading.warnings == [] and reading.seconds < FAST_S
    assert server.received == 0


def test_client_has_no_way_to_send(serve, monkeypatch):
    def refuse(*args, **kwargs):
        raise AssertionError("the primary client tried to send")

    for name in ("send", "sendall", "sendto", "sendmsg"):
        monkeypatch.setattr(socket.socket, name, refuse)
    server = serve([(VERSION_MESSAGE + ROBOT_STATE, 0.0)])
    assert read_primary(server.host).kinematics is not None
    stream = primary._open_read_only(server.host, 30012, 2.0)
    try:
        assert stream.readable() and not stream.writable()
        with pytest.raises(OSError):
            stream.write(b"x")
    finally:
        stream.close()
    assert server.received == 0


@pytest.mark.parametrize("port", [30001, 30002, 30003, 29999, 30004])
def test_only_read_only_ports_are_used(serve, port):
    server = serve([(VERSION_MESSAGE + ROBOT_STATE, 0.0)], port=port)
    with pytest.raises(ConfigError, match="30011 and 30012"):
        read_primary(server.host, port=port)
    with pytest.raises(ConfigError):
        read_arm_kinematics(server.host, "ur5e", port=port)
    time.sleep(0.05)
    assert server.connections == 0


def test_ursim_stream_gives_its_table_with_simulator_warnings(serve):
    server = serve([(VERSION_MESSAGE + ROBOT_STATE, 0.0)])
    result = read_arm_kinematics(server.host)
    assert result.calibrated and result.table.model == "ur5e"
    assert result.table.alpha[0] == 1.570796327
    assert result.nominal_difference.translation_mm < 1e-5
    assert any("status 0" in w for w in result.warnings)
    assert any("0xFFFFFFFF" in w for w in result.warnings)


def test_unknown_and_resized_subpackages_still_give_the_table(serve):
    parts = subpackages()
    parts[0] = (0, parts[0][1] + bytes(13))
    parts.insert(3, (77, b"\x01" * 30))
    parts[4] = (KINEMATICS_INFO, kinematics_payload() + b"\xaa" * 10)
    server = serve([(robot_state(parts), 0.0)])
    result = read_arm_kinematics(server.host, "ur5e")
    assert result.calibrated and result.reading.kinematics.extra_bytes == 10
    assert not any("NOMINAL" in w for w in result.warnings)


def test_table_in_a_later_message(serve):
    server = serve([(replaced(KINEMATICS_INFO, None), 0.1),
                    (replaced(KINEMATICS_INFO, kinematics_payload()[:4]), 0.1),
                    (ROBOT_STATE, 0.0)])
    reading = read_primary(server.host)
    assert reading.kinematics is not None and reading.messages == 3
    assert reading.short_kinematics == 1 and reading.warnings == []


def assert_nominal_with_warning(result, *needles: str) -> None:
    assert not result.calibrated
    assert result.table == nominal_table("ur5e")
    assert "NOMINAL ur5e" in result.warnings[-1]
    for needle in needles:
        assert any(needle in w for w in result.warnings), result.warnings


def test_truncated_message_gives_nominal_and_warning(serve):
    server = serve([(VERSION_MESSAGE + ROBOT_STATE[:700], 0.0)], close=True)
    result = read_arm_kinematics(server.host, "ur5e")
    assert_nominal_with_warning(result, "truncated message of 700 of 1386 bytes",
                                "connection closed")
    assert result.reading.version is not None and result.reading.seconds < FAST_S


def test_no_kinematics_within_the_time_limit_gives_nominal_and_warning(serve):
    no_table = replaced(KINEMATICS_INFO, None)
    server = serve([(VERSION_MESSAGE, 0.0)] + [(no_table, 0.1)] * 40)
    start = time.monotonic()
    result = read_arm_kinematics(server.host, "ur5e", timeout=2.0)
    assert 1.9 < time.monotonic() - start < 3.0
    assert_nominal_with_warning(result, "within 2 s")
    assert result.reading.messages >= 15


def test_silent_controller_gives_nominal_and_warning(serve):
    server = serve([])
    result = read_arm_kinematics(server.host, "ur5e", timeout=0.5)
    assert_nominal_with_warning(result, "0 complete messages")


def test_stream_out_of_step_gives_nominal_and_warning(serve):
    garbage = b"\x7f\xff\xff\xff\x10" + bytes(100)
    server = serve([(VERSION_MESSAGE + garbage + ROBOT_STATE, 0.0)])
    result = read_arm_kinematics(server.host, "ur5e")
    assert_nominal_with_warning(result, "out of step")
    assert result.reading.seconds < FAST_S


def test_malformed_state_gives_nominal_and_warning(serve):
    damaged = bytearray(ROBOT_STATE)
    damaged[5:9] = (5000).to_bytes(4, "big")  # first sub-package runs past the end
    server = serve([(bytes(damaged), 0.0)], close=True)
    result = read_arm_kinematics(server.host, "ur5e")
    assert_nominal_with_warning(result, "malformed ROBOT_STATE")


def test_nothing_listening():
    listener, host = _bind(30012)
    listener.close()  # the address is ours, nothing listens there
    start = time.monotonic()
    with pytest.raises(ConnectionFailed, match="30012"):
        read_primary(host)
    result = read_arm_kinematics(host, "ur5e")
    assert_nominal_with_warning(result, "cannot reach")
    assert time.monotonic() - start < FAST_S


def test_kinematics_of_another_model_are_refused(serve):
    server = serve([(VERSION_MESSAGE + ROBOT_STATE, 0.0)])
    with pytest.raises(ConfigError, match="really a ur10e"):
        read_arm_kinematics(server.host, "ur10e")


def test_bad_arguments():
    with pytest.raises(ConfigError, match="unknown robot model"):
        read_arm_kinematics("127.0.0.1", "ur20")
    with pytest.raises(ConfigError, match="timeout"):
        read_primary("127.0.0.1", timeout=0)
