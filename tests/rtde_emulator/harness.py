"""Test side: start an emulated controller in its own process on a fresh loopback address,
talk to it over its control channel, and always end it.

The emulator must run in another process: ur_rtde's constructors hold the GIL while they wait
for the controller, so an emulator thread in the test process would deadlock them.
"""

from __future__ import annotations

import itertools
import json
import os
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

REPO_ROOT = Path(__file__).resolve().parents[2]
START_TIMEOUT_S = 20.0
REQUEST_TIMEOUT_S = 10.0
_counter = itertools.count()


def free_loopback_address() -> str:
    """A 127.x.y.z (never 127.0.0.1, which ur_rtde treats specially) where nothing listens on
    the RTDE port. x comes from the process id, so parallel test processes do not collide."""
    x = 16 + os.getpid() % 224
    for n in _counter:
        host = f"127.{x}.{(n // 250) % 250}.{n % 250 + 2}"
        probe = socket.socket()
        probe.settimeout(0.5)
        try:
            if probe.connect_ex((host, 30004)) != 0:
                return host
        finally:
            probe.close()
    raise AssertionError("unreachable")


class EmulatedController:
    """A running emulator process (see ``python -m tests.rtde_emulator --help``)."""

    def __init__(self, *, robot: str = "ur5e", q0=None, version: str | None = None,
                 settings: dict | None = None, kinematics: str | None = None,
                 attempts: int = 5):
        for _ in range(attempts):
            self.host = free_loopback_address()
            cmd = [sys.executable, "-m", "tests.rtde_emulator", "--host", self.host,
                   "--robot", robot, "--settings", json.dumps(settings or {})]
            if q0 is not None:
                cmd += ["--q0", json.dumps([float(v) for v in q0])]
            if version is not None:
                cmd += ["--version", version]
            if kinematics is not None:
                cmd += ["--kinematics", kinematics]
            env = dict(os.environ, PYTHONPATH=os.pathsep.join(
                [str(REPO_ROOT)] + [p for p in [os.environ.get("PYTHONPATH")] if p]))
            self.proc = subprocess.Popen(cmd, stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                         env=env, text=True, bufsize=1)
            try:
                hello = self._read_line(START_TIMEOUT_S)
            except BaseException:
                self.close()
                raise
            if hello.get("ready"):
                self.rate_hz = hello["rate_hz"]
                return
            self.close()  # e.g. another process took the address meanwhile: next one
        raise RuntimeError(f"RTDE emulator did not start after {attempts} attempts: {hello}")

    def _read_line(self, timeout: float) -> dict:
        box: list[str] = []
        reader = threading.Thread(target=lambda: box.append(self.proc.stdout.readline()),
                                  daemon=True)
        reader.start()
        reader.join(timeout)
        if not box or not box[0]:
            raise RuntimeError(f"RTDE emulator at {self.host} did not answer within {timeout} s "
                               f"(exit status {self.proc.poll()})")
        return json.loads(box[0])

    def request(self, op: str, **fields) -> dict:
        """Send one control request and return the reply; RuntimeError if it failed."""
        self.proc.stdin.write(json.dumps({"op": op, **fields}) + "\n")
        self.proc.stdin.flush()
        reply = self._read_line(REQUEST_TIMEOUT_S)
        if not reply.get("ok"):
            raise RuntimeError(f"emulator request {op} failed: {reply.get('error')}")
        return reply

    def inject(self, kind: str, move: int, at: float = 0.5) -> None:
        """Arm a move fault: ``kind`` strikes during the ``move``-th move at share ``at``."""
        self.request("fault", kind=kind, move=move, at=at)

    def configure(self, **settings) -> None:
        self.request("set", **settings)

    def events(self, kind: str | None = None) -> list[dict]:
        events = self.request("events")["events"]
        return [e for e in events if kind is None or e["kind"] == kind]

    def commands(self) -> list[dict]:
        """The control-script commands the controller received, in order."""
        return self.events("command")

    def state(self) -> dict:
        return self.request("state")["state"]

    def wait_until_still(self, timeout: float = 2.0) -> dict:
        """The state once the arm is at rest (a stop brakes over a few cycles)."""
        deadline = time.monotonic() + timeout
        while (state := self.state())["moving"]:
            if time.monotonic() > deadline:
                raise AssertionError(f"emulated arm at {self.host} still moving after "
                                     f"{timeout} s: {state}")
            time.sleep(0.01)
        return state

    def close(self) -> None:
        """Ask the emulator to quit; kill it if it does not within 3 s. Idempotent."""
        if self.proc.poll() is None:
            try:
                self.proc.stdin.write('{"op": "quit"}\n')
                self.proc.stdin.flush()
                self.proc.wait(3.0)
            except (OSError, subprocess.TimeoutExpired):
                self.proc.kill()
                self.proc.wait(3.0)
        for stream in (self.proc.stdin, self.proc.stdout):
            try:
                stream.close()
            except OSError:
                pass
