"""Read a UR controller's calibrated kinematics from its read-only primary/secondary ports.

Safety rule: ports 30001 and 30002 run as URScript whatever a client writes to them. This client
connects only to their documented read-only twins, 30011 (primary) and 30012 (secondary), and it
cannot send: right after connecting it keeps nothing but a read-only stream over the socket
(``socket.makefile("rb")``, whose ``write`` raises) and drops the socket object itself. There is
no code path here that writes, on any port.

What it reads (layouts in :mod:`drivers.ur.primary_format`): the version message a controller
sends on connect, and the first ROBOT_STATE that carries a full KINEMATICS_INFO (sent at 10 Hz,
the first one right after connecting), together with the actual joints and TCP pose of that same
message. It stops at that message or after ``timeout`` seconds.

Stream problems never raise: truncated or malformed messages, unknown or resized sub-packages,
silence, a closed connection all end in a :class:`PrimaryReading` without kinematics (or with
the last complete one) and warnings that say what happened; :func:`read_arm_kinematics` then
falls back to the nominal table of the expected model with a warning. Only an unreachable port
raises (ConnectionFailed) from :func:`read_primary`.
"""

from __future__ import annotations

import logging
import select
import socket
import time
from dataclasses import dataclass, field

import numpy as np

from armstereo.errors import ConfigError, ConnectionFailed
from armstereo.robot.dh import (
    CALIBRATION_LINEARISED,
    NOMINAL_MODELS,
    SOURCE_CONTROLLER,
    DHTable,
    FKDifference,
    fk_difference,
    identify_model,
    nominal_table,
    workspace_joints,
)
from drivers.ur.primary_format import (
    ROBOT_MESSAGE,
    ROBOT_STATE,
    KinematicsInfo,
    MessageSplitter,
    VersionInfo,
    parse_robot_state,
    parse_version_message,
)

log = logging.getLogger(__name__)

PRIMARY_READ_ONLY_PORT = 30011
SECONDARY_READ_ONLY_PORT = 30012
READ_ONLY_PORTS = (PRIMARY_READ_ONLY_PORT, SECONDARY_READ_ONLY_PORT)
EXECUTING_PORTS = (30001, 30002)  # never connected to: they run what they receive
DEFAULT_PORT = SECONDARY_READ_ONLY_PORT
KINEMATICS_TIMEOUT_S = 2.0  # the table comes in the first state message, within 0.1 s
READ_CHUNK = 65536
URSIM_CHECKSUM = 0xFFFFFFFF  # what URSim reports for every joint
# A calibrated arm is millimetres from its own nominal model; farther than this from every
# nominal model means it is not the model named (or not a supported one).
WRONG_MODEL_MM = 20.0
WRONG_MODEL_DEG = 3.0
CB3_MODELS = ("ur5",)


@dataclass
class PrimaryReading:
    """What :func:`read_primary` got. ``joints`` (rad), ``tcp_pose`` (UR pose in ``base``) and
    ``tcp_offset`` (UR pose of the TCP in the flange frame) come from the same message as
    ``kinematics``; each is None if it was not read."""

    host: str
    port: int
    kinematics: KinematicsInfo | None = None
    version: VersionInfo | None = None
    joints: np.ndarray | None = None
    tcp_pose: np.ndarray | None = None
    tcp_offset: np.ndarray | None = None
    messages: int = 0  # complete messages read
    short_kinematics: int = 0  # KINEMATICS_INFO sub-packages too short to hold a table
    seconds: float = 0.0  # from connected to done
    warnings: list[str] = field(default_factory=list)


def read_primary(host: str, *, port: int = DEFAULT_PORT,
                 timeout: float = KINEMATICS_TIMEOUT_S) -> PrimaryReading:
    """Connect read-only to ``host:port`` (30011 or 30012) and read until the first full
    KINEMATICS_INFO, at most ``timeout`` s after connecting. Raises ConfigError for another
    port or a bad timeout, ConnectionFailed if the port cannot be reached; never for what the
    stream holds."""
    if port not in READ_ONLY_PORTS:
        raise ConfigError(f"port {port} is not a read-only UR port; only "
                          f"{' and '.join(map(str, READ_ONLY_PORTS))} are used (ports "
                          f"{' and '.join(map(str, EXECUTING_PORTS))} execute what they receive)")
    if not (np.isfinite(timeout) and timeout > 0):
        raise ConfigError(f"timeout must be positive seconds, got {timeout!r}")
    stream = _open_read_only(host, port, timeout)
    try:
        return read_primary_stream(stream, host, port, timeout=timeout)
    finally:
        stream.close()


def read_primary_stream(stream, host: str, port: int, *,
                        timeout: float = KINEMATICS_TIMEOUT_S) -> PrimaryReading:
    """Read an already open, read-only primary stream (anything ``select`` accepts with a
    ``read(n)``) until the first full KINEMATICS_INFO, at most ``timeout`` s. ``host`` and
    ``port`` only name the source in warnings. This is what :func:`read_primary` does after
    connecting; simulated controllers (the mock arm) feed their broadcast through it, so their
    tables are decoded by exactly the code that decodes a real controller's."""
    reading = PrimaryReading(host, port)
    start = time.monotonic()
    _read_until_kinematics(stream, reading, start + timeout, timeout)
    reading.seconds = time.monotonic() - start
    return reading


def _open_read_only(host: str, port: int, timeout: float):
    """A read-only, unbuffered stream over a new connection; the socket object is dropped."""
    try:
        sock = socket.create_connection((host, port), timeout=timeout)
    except socket.gaierror as err:
        raise ConnectionFailed(f"cannot resolve UR controller host {host!r}: {err}") from err
    except OSError as err:
        reason = "no answer" if isinstance(err, TimeoutError) else (err.strerror or str(err))
        raise ConnectionFailed(f"cannot reach UR controller at {host}:{port} ({reason}): check "
                               f"the IP, that the robot is on and that PolyScope's security "
                               f"settings do not block port {port}") from err
    stream = sock.makefile("rb", buffering=0)
    sock.close()  # the stream keeps the connection open; nothing that can send is left
    return stream


def _read_until_kinematics(stream, reading: PrimaryReading, deadline: float,
                           timeout: float) -> None:
    splitter = MessageSplitter()
    while True:
        left = deadline - time.monotonic()
        if left <= 0:
            reading.warnings.append(_silence_note(reading, splitter, f"within {timeout:g} s"))
            return
        try:
            ready, _, _ = select.select([stream], [], [], left)
            chunk = stream.read(READ_CHUNK) if ready else None
        except OSError as err:
            reading.warnings.append(f"reading UR controller at {reading.host}:{reading.port} "
                                    f"failed ({err})")
            return
        if chunk is None:
            continue
        if not chunk:
            reading.warnings.append(_silence_note(reading, splitter, "before the connection "
                                                                     "closed"))
            return
        for kind, body in splitter.feed(chunk):
            reading.messages += 1
            if _take_message(reading, kind, body):
                return
        if splitter.error:
            reading.warnings.append(f"UR controller at {reading.host}:{reading.port}: "
                                    f"{splitter.error}; stopped reading")
            return


def _take_message(reading: PrimaryReading, kind: int, body: bytes) -> bool:
    """Use one complete message; True once a full KINEMATICS_INFO has been read."""
    if kind == ROBOT_MESSAGE:
        try:
            version = parse_version_message(body)
        except ValueError as err:
            reading.warnings.append(f"version message ignored: {err}")
            return False
        if version is not None:
            reading.version = version
        return False
    if kind != ROBOT_STATE:
        return False
    state = parse_robot_state(body)
    reading.short_kinematics += state.short_kinematics
    for note in state.notes:
        log.debug("%s:%s: %s", reading.host, reading.port, note)
    if not state.valid:  # the same damage every 100 ms is one warning, not twenty
        reading.warnings.extend(n for n in state.notes if n not in reading.warnings)
        return False
    if state.kinematics is None:
        return False
    reading.kinematics = state.kinematics
    reading.joints, reading.tcp_pose, reading.tcp_offset = (state.joints, state.tcp_pose,
                                                            state.tcp_offset)
    return True


def _silence_note(reading: PrimaryReading, splitter: MessageSplitter, when: str) -> str:
    held, size = splitter.pending
    text = (f"no complete KINEMATICS_INFO from UR controller at {reading.host}:{reading.port} "
            f"{when} ({reading.messages} complete messages read")
    if reading.short_kinematics:
        text += (f"; {reading.short_kinematics} KINEMATICS_INFO sub-packages too short to hold "
                 f"a table skipped")
    if held:
        text += (f"; a truncated message of {held} of {size} bytes was dropped" if size
                 else f"; {held} stray bytes dropped")
    return text + ")"


@dataclass(frozen=True)
class ArmKinematics:
    """The kinematics to use for an arm: its controller's calibrated table, or the nominal one
    with ``warnings`` saying why. ``nominal_difference``: calibrated vs nominal FK, largest
    over the workspace sample (None when the table is nominal)."""

    table: DHTable
    reading: PrimaryReading | None
    warnings: tuple[str, ...]
    nominal_difference: FKDifference | None = None

    @property
    def calibrated(self) -> bool:
        return self.table.source == SOURCE_CONTROLLER


def read_arm_kinematics(host: str, model: str | None = None, *, port: int = DEFAULT_PORT,
                        timeout: float = KINEMATICS_TIMEOUT_S) -> ArmKinematics:
    """The controller's calibrated DH table, read-only (see :func:`read_primary`).

    ``model``: the UR model the caller expects (None: identify it from the table). Stream or
    connection problems give the nominal table of ``model`` (ur5e if None) with warnings. Raises
    ConfigError only for bad arguments or when the controller's kinematics are not those of
    ``model`` (or of any supported model): using them would be wrong either way.
    """
    expected = str(model).lower() if model is not None else None
    if expected is not None and expected not in NOMINAL_MODELS:
        raise ConfigError(f"unknown robot model {model!r}; known: {', '.join(NOMINAL_MODELS)}")
    try:
        reading = read_primary(host, port=port, timeout=timeout)
    except ConnectionFailed as err:
        return _nominal(expected, None, [str(err)])
    return kinematics_from_reading(reading, expected)


def kinematics_from_reading(reading: PrimaryReading, model: str | None = None) -> ArmKinematics:
    """The table to use from what :func:`read_primary` (or :func:`read_primary_stream`) got:
    the controller's calibrated table, or the nominal table of ``model`` with warnings. Raises
    ConfigError as :func:`read_arm_kinematics` does."""
    expected = str(model).lower() if model is not None else None
    if reading.kinematics is None:
        return _nominal(expected, reading, reading.warnings)
    table, difference = _controller_table(reading, expected)
    return ArmKinematics(table, reading, tuple(reading.warnings + _status_warnings(table)),
                         difference)


def _nominal(model: str | None, reading: PrimaryReading | None,
             warnings: list[str]) -> ArmKinematics:
    name = model or "ur5e"
    note = (f"using the NOMINAL {name} kinematics: camera poses may be off by millimetres "
            f"from where the arm really is")
    return ArmKinematics(nominal_table(name), reading, tuple(warnings) + (note,))


def _controller_table(reading: PrimaryReading,
                      expected: str | None) -> tuple[DHTable, FKDifference]:
    k = reading.kinematics
    raw = DHTable(model="", theta=k.theta, a=k.a, d=k.d, alpha=k.alpha,
                  source=SOURCE_CONTROLLER, calibration_status=k.calibration_status,
                  checksums=k.checksums)
    candidates = NOMINAL_MODELS
    if reading.version is not None:
        cb3 = reading.version.major < 5
        candidates = tuple(m for m in NOMINAL_MODELS if (m in CB3_MODELS) == cb3) or candidates
    closest, difference = identify_model(raw, candidates)
    name = expected or closest
    if expected is not None and expected != closest:
        difference = fk_difference(raw, nominal_table(expected), workspace_joints(200))
    if difference.translation_mm > WRONG_MODEL_MM or difference.rotation_deg > WRONG_MODEL_DEG:
        what = f"a {expected}" if expected else "any supported model"
        raise ConfigError(
            f"UR controller at {reading.host} reports kinematics {difference.translation_mm:.0f} "
            f"mm / {difference.rotation_deg:.1f} deg from {what} (closest: {closest}): is this "
            f"arm really a {name}?")
    table = DHTable(model=name, theta=k.theta, a=k.a, d=k.d, alpha=k.alpha,
                    source=SOURCE_CONTROLLER, calibration_status=k.calibration_status,
                    checksums=k.checksums)
    return table, fk_difference(table, nominal_table(name), workspace_joints())


def _status_warnings(table: DHTable) -> list[str]:
    out = []
    if table.calibration_status != CALIBRATION_LINEARISED:
        out.append(f"the controller reports calibration status {table.calibration_status} "
                   f"({table.status_text}), not {CALIBRATION_LINEARISED} (linearised): a "
                   f"simulator or an arm without a factory calibration")
    if table.checksums and all(c == URSIM_CHECKSUM for c in table.checksums):
        out.append("every joint checksum is 0xFFFFFFFF, as URSim reports: this is probably a "
                   "simulator, whose table is the nominal one")
    return out
