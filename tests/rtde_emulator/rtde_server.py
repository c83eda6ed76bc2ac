"""RTDE on port 30004: one session per client connection, and the controller clock that steps
the controller and streams every started session's output recipe at its requested rate.

Rules a real controller enforces and ur_rtde relies on: input recipes are numbered 1, 2, 3, ...
per connection in setup order; an input field another live connection has claimed is answered
``IN_USE`` (the recipe is refused, id 0) until that connection closes; unknown outputs are
answered ``NOT_FOUND``.
"""

from __future__ import annotations

import itertools
import socket
import struct
import threading
import time

from . import protocol as P
from .controller import Controller
from .protocol import INPUT_TYPES, OUTPUT_TYPES, PackageReader

MAX_CATCH_UP_S = 0.1  # longest single step when the clock thread was held up


class InputOwners:
    """Which live connection has claimed which input field."""

    def __init__(self) -> None:
        self._owner: dict[str, int] = {}
        self._lock = threading.Lock()

    def claim(self, session_id: int, names: list[str]) -> list[str]:
        """Claim ``names`` for the session; the names another session holds (then nothing is
        claimed)."""
        with self._lock:
            taken = [n for n in names if self._owner.get(n, session_id) != session_id]
            if not taken:
                self._owner.update(dict.fromkeys(names, session_id))
            return taken

    def release(self, session_id: int) -> None:
        with self._lock:
            self._owner = {n: s for n, s in self._owner.items() if s != session_id}


class RtdeSession:
    """One RTDE client connection: handshake, recipes, client data, and outgoing stream."""

    _ids = itertools.count(1)

    def __init__(self, sock: socket.socket, controller: Controller, owners: InputOwners):
        self.id = next(self._ids)
        self.sock = sock
        self.c = controller
        self.owners = owners
        self.send_lock = threading.Lock()
        self.outputs: list[str] = []
        self.output_struct: struct.Struct | None = None
        self.period = 0.0
        self.inputs: dict[int, tuple[list[str], struct.Struct]] = {}
        self.next_input_id = 1
        self.stream_from: float | None = None  # controller time of the first package
        self.next_send = 0.0
        self.alive = True

    def serve(self) -> None:
        """Handle requests until the client goes away."""
        reader = PackageReader(self.sock)
        try:
            while self.alive and (package := reader.read()) is not None:
                self._handle(*package)
        finally:
            self.close()

    def close(self) -> None:
        if self.alive:
            self.alive = False
            self.owners.release(self.id)
            with self.c.lock:
                self.c.log("rtde_closed", session=self.id)
        try:
            self.sock.close()
        except OSError:
            pass

    def send(self, data: bytes) -> None:
        try:
            with self.send_lock:
                self.sock.sendall(data)
        except OSError:
            self.close()

    def _handle(self, kind: int, body: bytes) -> None:
        if kind == P.REQUEST_PROTOCOL_VERSION:
            version = struct.unpack(">H", body[:2])[0] if len(body) >= 2 else 0
            self.send(P.pack(kind, bytes([1 if version in (1, 2) else 0])))
        elif kind == P.GET_URCONTROL_VERSION:
            self.send(P.pack(kind, struct.pack(">IIII", *self.c.version)))
        elif kind == P.SETUP_OUTPUTS:
            self._setup_outputs(body)
        elif kind == P.SETUP_INPUTS:
            self._setup_inputs(body)
        elif kind == P.START:  # answer first: ur_rtde reads the next package as the answer
            self.send(P.pack(kind, b"\x01" if self.output_struct else b"\x00"))
            if self.output_struct is None:
                return
            with self.c.lock:
                self.next_send = self.c.time + self.c.settings.start_delay_s
                self.stream_from = self.next_send
                self.c.log("rtde_start", session=self.id, outputs=len(self.outputs))
        elif kind == P.PAUSE:
            self.stream_from = None
            self.send(P.pack(kind, b"\x01"))
        elif kind == P.DATA_PACKAGE:
            self._client_data(body)
        else:
            with self.c.lock:
                self.c.log("protocol_error", session=self.id, detail=f"package type {kind}")

    def _setup_outputs(self, body: bytes) -> None:
        frequency = struct.unpack(">d", body[:8])[0]
        names = P.names_of(body[8:])
        types = [OUTPUT_TYPES.get(n, "NOT_FOUND") for n in names]
        if "NOT_FOUND" not in types:
            self.outputs = names
            self.output_struct = P.recipe_struct(types)
            rate = self.c.rate_hz
            self.period = 1.0 / (rate if not 0 < frequency <= rate else frequency)
        with self.c.lock:
            self.c.log("rtde_outputs", session=self.id, frequency=frequency, names=names)
        self.send(P.pack(P.SETUP_OUTPUTS, b"\x01" + ",".join(types).encode()))

    def _setup_inputs(self, body: bytes) -> None:
        names = P.names_of(body)
        types = [INPUT_TYPES.get(n, "NOT_FOUND") for n in names]
        taken = [] if "NOT_FOUND" in types else self.owners.claim(self.id, names)
        recipe = 0
        if taken:
            types = ["IN_USE" if n in taken else t for n, t in zip(names, types, strict=True)]
            with self.c.lock:
                self.c.log("inputs_in_use", session=self.id, names=taken)
        elif "NOT_FOUND" not in types:
            recipe = self.next_input_id
            self.next_input_id += 1
            self.inputs[recipe] = (names, P.recipe_struct(types))
        self.send(P.pack(P.SETUP_INPUTS, bytes([recipe]) + ",".join(types).encode()))

    def _client_data(self, body: bytes) -> None:
        recipe = body[0] if body else 0
        names, fmt = self.inputs.get(recipe, (None, None))
        if fmt is None or len(body) != fmt.size:
            with self.c.lock:
                self.c.log("protocol_error", session=self.id,
                           detail=f"data for recipe {recipe}: {len(body)} bytes")
            return
        flat = list(fmt.unpack(body)[1:])
        values = {}
        for name in names:
            width = P.width(INPUT_TYPES[name])
            values[name], flat = (flat[0] if width == 1 else flat[:width]), flat[width:]
        with self.c.lock:
            self.c.write_inputs(values)

    def due(self, now: float) -> bool:
        """True if a package should go out at controller time ``now``."""
        return (self.alive and self.output_struct is not None and self.stream_from is not None
                and now >= self.next_send)

    def stream(self, now: float, values: dict[str, object]) -> None:
        """Send one output package built from ``values``."""
        self.next_send = max(self.next_send + self.period, now + self.period / 2)
        payload = self.output_struct.pack(
            1, *P.flatten([values[n] for n in self.outputs]))
        self.send(P.pack(P.DATA_PACKAGE, payload))


class ControllerClock:
    """Steps the controller every cycle (2 ms e-Series, 8 ms CB3) and streams the sessions."""

    def __init__(self, controller: Controller, on_network_down) -> None:
        self.c = controller
        self.sessions: list[RtdeSession] = []
        self._sessions_lock = threading.Lock()  # sessions join from the accept threads
        self.on_network_down = on_network_down
        self.running = True
        self._dropped = False
        self.thread = threading.Thread(target=self._run, name="controller-clock", daemon=True)

    def add(self, session: RtdeSession) -> None:
        with self._sessions_lock:
            self.sessions.append(session)

    def _run(self) -> None:
        period = 1.0 / self.c.rate_hz
        next_t = time.monotonic()
        while self.running:
            next_t += period
            delay = next_t - time.monotonic()
            dt = period
            if delay > 0:
                time.sleep(delay)
            else:  # late: the controller's time keeps pace with the wall clock
                missed = min(int(-delay / period), int(MAX_CATCH_UP_S / period))
                next_t += missed * period
                dt += missed * period
            self._cycle(dt)

    def _cycle(self, period: float) -> None:
        with self._sessions_lock:
            self.sessions = [s for s in self.sessions if s.alive]
            sessions = list(self.sessions)
        with self.c.lock:
            self.c.step(period)
            now = self.c.time
            due = [s for s in sessions if s.due(now)]
            names = set().union(*(s.outputs for s in due)) if due else set()
            values = self.c.output_values(names)
            network_down = self.c.network_down
        for s in due:
            s.stream(now, values)
        if network_down and not self._dropped:
            self._dropped = True
            self.on_network_down()
