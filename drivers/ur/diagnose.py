"""Turn ur_rtde's connection errors into one-line ConnectionFailed messages with a remedy.

ur_rtde reports every constructor failure as a RuntimeError whose text says what went wrong;
the table below matches those texts (ur_rtde 1.6.x) and names the host and what to do.
"""

from __future__ import annotations

from armstereo.errors import ConnectionFailed

# (text ur_rtde puts in the error, lower case) -> what we tell the user; {host} and {msg} filled in
_HINTS: tuple[tuple[str, str], ...] = (
    ("could not connect to",
     "cannot reach UR controller at {host}:30004 ({msg}): check the IP and that the robot is on"),
    ("remote control",
     "UR controller at {host} is not in Remote Control ({msg}): enable it in the pendant's "
     "settings (System > Remote Control) and switch the pendant to Remote"),
    ("already in use",
     "UR controller at {host}: its RTDE input registers are in use by another client "
     "(a second ur_rtde control interface, EtherNet/IP, PROFINET or MODBUS): close that client "
     "or connect with upper_range_registers=True"),
    ("failed to start control script",
     "UR controller at {host} did not start ur_rtde's control script ({msg}): power the arm on, "
     "release the brakes, clear any protective stop, stop the program on the pendant and, on "
     "e-Series, enable Remote Control"),
    ("dashboard",
     "cannot use the dashboard server of UR controller at {host}:29999 ({msg}): check that the "
     "controller is booted and nothing blocks port 29999"),
    ("was not found by the controller",
     "UR controller at {host} lacks an RTDE variable armstereo needs ({msg}): update PolyScope"),
)


def connection_failed(host: str, interface: str, err: BaseException) -> ConnectionFailed:
    """The ConnectionFailed for an exception raised while opening ur_rtde's ``interface``
    ("receive" or "control") to ``host``."""
    msg = " ".join(str(err).split()) or type(err).__name__
    low = msg.lower()
    for needle, text in _HINTS:
        if needle in low:
            return ConnectionFailed(text.format(host=host, msg=msg))
    return ConnectionFailed(f"UR controller at {host}: opening the RTDE {interface} interface "
                            f"failed: {msg}")
