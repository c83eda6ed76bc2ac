"""One exception hierarchy for armstereo.

Every error the CLI can meet derives from :class:`ArmstereoError`; the CLI prints ``str(err)``
on one line and exits with ``err.exit_code``. Messages name the offending value and the limit.
"""

from __future__ import annotations


class ArmstereoError(Exception):
    """Base class: a problem a user can act on. ``exit_code`` is what the CLI returns."""

    exit_code = 1


class ConfigError(ArmstereoError):
    """Bad user input: arguments, files, model names, mount files."""

    exit_code = 2


class PreflightError(ArmstereoError):
    """A capture plan was refused before anything moved (unreachable, unsafe, out of limits)."""

    exit_code = 3


class KinematicsError(ArmstereoError):
    """Kinematics could not answer (see subclasses)."""

    exit_code = 3


class IKError(KinematicsError):
    """Inverse kinematics failed; ``reason`` says why (no convergence, joint limits, singular)."""

    def __init__(self, message: str, reason: str = "no_convergence"):
        super().__init__(message)
        self.reason = reason


class JointLimitError(KinematicsError):
    """A joint vector is outside the model's limits (with the margin asked for)."""


class HardwareError(ArmstereoError):
    """The arm or camera failed while in use."""

    exit_code = 4


class ConnectionFailed(HardwareError):
    """Could not connect to a device (names the host or device)."""


class NotConnected(HardwareError):
    """A device was used before ``connect()`` or after ``close()``, or connected twice."""


class ConnectionLost(HardwareError):
    """An established connection dropped."""


class ProtectiveStop(HardwareError):
    """The controller entered a protective stop."""


class EmergencyStop(HardwareError):
    """The controller reports an emergency stop."""


class MotionTimeout(HardwareError):
    """A move did not finish in the time allowed."""


class CameraTimeout(HardwareError):
    """The camera delivered no frame in the time allowed."""


class RecordingError(ArmstereoError):
    """A recording is unreadable, truncated beyond use, or lacks what is needed."""

    exit_code = 5


class OutputError(ArmstereoError):
    """An output could not be written (disk full, read-only file system, no permission); the
    message names the path. Outputs completed before it are kept."""

    exit_code = 5


class StereoError(ArmstereoError):
    """Rectification, matching or reconstruction cannot run on this input."""

    exit_code = 6


class UserAbort(ArmstereoError):
    """The user declined the confirmation or interrupted the run."""

    exit_code = 130
