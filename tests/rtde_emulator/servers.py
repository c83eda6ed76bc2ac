"""The controller's TCP servers on one loopback address: RTDE (30004), the dashboard server
(29999, line based) and the script port (30003, where ur_rtde uploads its control program).

The script port of a real controller also streams robot state; ur_rtde never reads it, so this
one only listens. Replies of the dashboard are the texts ur_rtde checks ("Stopped",
"Protective stop releasing", a version number, digits for the serial number, "true").
"""

from __future__ import annotations

import re
import socket
import threading
from collections.abc import Callable

from .controller import Controller
from .rtde_server import ControllerClock, InputOwners, RtdeSession

RTDE_PORT, DASHBOARD_PORT, SCRIPT_PORT = 30004, 29999, 30003
SERIAL_NUMBER = "20235500001"
ROBOT_MODE_NAMES = {3: "POWER_OFF", 4: "POWER_ON", 5: "IDLE", 7: "RUNNING"}
_PROGRAM_END = re.compile(r"^end[ \t]*$", re.M)


class Network:
    """Listening sockets and every accepted connection, so a fault can drop them all."""

    def __init__(self, host: str):
        self.host = host
        self.listeners: list[socket.socket] = []
        self.clients: set[socket.socket] = set()
        self.lock = threading.Lock()
        self.down = False

    def listen(self, port: int, session: Callable[[socket.socket], None]) -> None:
        """Bind ``host:port`` (SO_REUSEADDR) and serve each connection on its own thread.
        Raises OSError if the address is taken."""
        sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        sock.bind((self.host, port))
        sock.listen(8)
        self.listeners.append(sock)
        threading.Thread(target=self._accept, args=(sock, session), daemon=True,
                         name=f"listen-{port}").start()

    def _accept(self, sock: socket.socket, session: Callable[[socket.socket], None]) -> None:
        while True:
            try:
                client, _ = sock.accept()
            except OSError:
                return
            client.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            with self.lock:
                if self.down:
                    client.close()
                    continue
                self.clients.add(client)
            threading.Thread(target=self._serve, args=(client, session), daemon=True).start()

    def _serve(self, client: socket.socket, session: Callable[[socket.socket], None]) -> None:
        try:
            session(client)
        finally:
            with self.lock:
                self.clients.discard(client)
            client.close()

    def drop(self) -> None:
        """Stop listening and close every connection: clients read end of stream, and new
        connections are refused (a controller that went away)."""
        with self.lock:
            self.down = True
            socks = self.listeners + list(self.clients)
        for s in socks:
            for action in (lambda s=s: s.shutdown(socket.SHUT_RDWR), s.close):
                try:
                    action()
                except OSError:
                    pass


def start_servers(host: str, controller: Controller) -> tuple[Network, ControllerClock]:
    """Listen on the three ports of ``host`` and start the controller clock."""
    network = Network(host)
    owners = InputOwners()
    clock = ControllerClock(controller, network.drop)

    def rtde(sock: socket.socket) -> None:
        session = RtdeSession(sock, controller, owners)
        clock.add(session)
        session.serve()

    network.listen(RTDE_PORT, rtde)
    network.listen(DASHBOARD_PORT, lambda sock: dashboard_session(sock, controller))
    network.listen(SCRIPT_PORT, lambda sock: script_session(sock, controller))
    clock.thread.start()
    return network, clock


def dashboard_session(sock: socket.socket, c: Controller) -> None:
    """Line-based dashboard server: welcome line, then one answer per command line."""
    buffer = b""
    try:
        sock.sendall(b"Connected: Universal Robots Dashboard Server\n")
        while chunk := sock.recv(4096):
            buffer += chunk
            while b"\n" in buffer:
                line, buffer = buffer.split(b"\n", 1)
                command = line.decode("ascii", "replace").strip()
                with c.lock:
                    answer = _dashboard_answer(command, c)
                    c.log("dashboard", command=command, answer=answer)
                sock.sendall(answer.encode() + b"\n")
                if command == "quit":
                    return
    except OSError:
        return


def _dashboard_answer(command: str, c: Controller) -> str:
    """The dashboard server's reply line to ``command`` (state changes happen here)."""
    playing = c.runtime_state == 2
    if command == "stop":
        c.end_program("dashboard stop")
        return "Stopped"
    if command == "unlock protective stop":
        if c.unlock_protective_stop():
            return "Protective stop releasing"
        return ("Cannot unlock protective stop until 5s after occurrence. Always inspect cause "
                "of protective stop before unlocking")
    answers = {
        "PolyscopeVersion": f"URSoftware {'.'.join(str(v) for v in c.version)} (emulated)",
        "get serial number": SERIAL_NUMBER,
        "is in remote control": "true" if c.settings.remote_control else "false",
        "close safety popup": "closing safety popup",
        "robotmode": f"Robotmode: {ROBOT_MODE_NAMES.get(c.robot_mode, c.robot_mode)}",
        "safetystatus": "Safetystatus: " + ("NORMAL" if c.safety_mode == 1
                                            else "PROTECTIVE_STOP"),
        "running": f"Program running: {'true' if playing else 'false'}",
        "programState": ("PLAYING" if playing else "STOPPED") + " rtde_control",
        "quit": "Disconnected",
    }
    return answers.get(command, f"could not understand: '{command}'")


def script_session(sock: socket.socket, c: Controller) -> None:
    """Collect uploaded text; each complete ``def name(): ... end`` program is started."""
    text = ""
    while True:
        try:
            chunk = sock.recv(65536)
        except OSError:
            chunk = b""
        if not chunk:
            return
        text += chunk.decode("utf-8", "replace")
        while (start := text.find("def ")) >= 0 and (end := _PROGRAM_END.search(text, start)):
            program, text = text[start:end.end()], text[end.end():]
            with c.lock:
                c.upload_program(program)
