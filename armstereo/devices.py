"""The interfaces every arm and camera backend implements.

Frames: joint positions in radians (UR order: shoulder_pan, shoulder_lift, elbow, wrist_1,
wrist_2, wrist_3); Cartesian targets are flange (``tool0``) poses ``T_base_flange`` as 4x4
arrays in the controller's ``base`` frame. Images are numpy uint8, BGR when color.
"""

from __future__ import annotations

import enum
import math
from abc import ABC, abstractmethod
from dataclasses import dataclass

import numpy as np

from armstereo.camera_model import Intrinsics
from armstereo.clock import Clock
from armstereo.errors import HardwareError, NotConnected
from armstereo.frame import Frame

__all__ = ["MAX_JOINT_ACCELERATION", "MAX_JOINT_SPEED", "MAX_LINEAR_ACCELERATION",
           "MAX_LINEAR_SPEED", "Arm", "ArmState", "ArmStatus", "Camera", "Device", "Frame",
           "MotionLimits", "trapezoid_duration"]


class ArmState(enum.Enum):
    """What the controller says about the arm's safety and connection."""

    NORMAL = "normal"
    PROTECTIVE_STOP = "protective_stop"
    EMERGENCY_STOP = "emergency_stop"
    DISCONNECTED = "disconnected"


@dataclass(frozen=True)
class ArmStatus:
    """The arm's state plus a human-readable detail (e.g. the controller's mode names)."""

    state: ArmState
    detail: str = ""

    @property
    def ok(self) -> bool:
        return self.state is ArmState.NORMAL


@dataclass(frozen=True)
class MotionLimits:
    """Caps applied to every move. Slow defaults: a capture is not a race.

    ``joint_speed`` rad/s, ``joint_acceleration`` rad/s^2 (moveJ); ``linear_speed`` m/s,
    ``linear_acceleration`` m/s^2 (moveL).
    """

    joint_speed: float = 0.5
    joint_acceleration: float = 1.0
    linear_speed: float = 0.05
    linear_acceleration: float = 0.25


# Hard ceilings no CLI flag can exceed (well below UR's own limits of 3.14 rad/s and 3 m/s).
MAX_JOINT_SPEED = 1.0
MAX_JOINT_ACCELERATION = 2.0
MAX_LINEAR_SPEED = 0.25
MAX_LINEAR_ACCELERATION = 1.0


def trapezoid_duration(distance: float, speed: float, acceleration: float) -> float:
    """Duration (s) of a rest-to-rest trapezoidal move: ``d/v + v/a`` when the cruise speed is
    reached (``d >= v^2/a``), else the triangular ``2 sqrt(d/a)``."""
    if distance <= 0:
        return 0.0
    if distance >= speed * speed / acceleration:
        return distance / speed + speed / acceleration
    return 2.0 * math.sqrt(distance / acceleration)


class Device(ABC):
    """The life cycle every arm and camera shares: ``connect()``, use, ``close()`` (or a
    ``with`` block). Using a device that is not connected, or connecting it twice, raises
    :class:`armstereo.errors.NotConnected` naming the device."""

    name: str = "device"
    _connected: bool = False  # set by connect()/close(); the guards read only this flag

    @abstractmethod
    def connect(self) -> None:
        """Open the device; raises ConnectionFailed naming it (host, index, path). A connect
        that fails half way leaves nothing open."""

    @abstractmethod
    def close(self) -> None:
        """Release the device (an arm stops first). Safe to call twice; never raises."""

    @property
    def is_connected(self) -> bool:
        """True between a successful connect() and close()."""
        return self._connected

    def __enter__(self):
        self.connect()
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def _require_connected(self) -> None:
        if not self._connected:
            raise NotConnected(f"{self.name}: not connected; call connect() first")

    def _require_not_connected(self) -> None:
        if self._connected:
            raise NotConnected(f"{self.name}: already connected; close() it first")


class Arm(Device):
    """A 6-DoF arm. Every method that moves blocks until the move ends or raises.

    Errors: :class:`armstereo.errors.ConnectionFailed` / ``ConnectionLost`` / ``ProtectiveStop`` /
    ``EmergencyStop`` / ``MotionTimeout`` / ``NotConnected``. On any error during a move the
    backend stops the arm before raising.
    """

    name: str = "arm"
    clock: Clock

    @abstractmethod
    def joint_positions(self) -> np.ndarray:
        """Actual joint positions (6,), radians, as fresh as the backend can give them."""

    @abstractmethod
    def move_joints(self, q: np.ndarray, speed: float, acceleration: float,
                    timeout: float = 60.0) -> None:
        """Joint-space move to ``q`` (radians) at ``speed`` rad/s, ``acceleration`` rad/s^2."""

    @abstractmethod
    def move_linear(self, T_base_flange: np.ndarray, speed: float, acceleration: float,
                    timeout: float = 60.0) -> None:
        """Straight-line flange move to ``T_base_flange`` (base frame), speed m/s, accel m/s^2."""

    @abstractmethod
    def wait_until_steady(self, timeout: float = 10.0) -> None:
        """Block until the arm is at rest; raises MotionTimeout after ``timeout`` seconds."""

    @abstractmethod
    def stop(self) -> None:
        """Decelerate to a stop now. Never raises because the link is down."""

    @abstractmethod
    def status(self) -> ArmStatus:
        """Safety/connection state, without raising."""

    @abstractmethod
    def recover_protective_stop(self, timeout: float = 15.0) -> None:
        """Release a protective stop (what the pendant's 'unlock' does) so the arm can move
        again; raises HardwareError if it is still stopped after ``timeout`` seconds."""

    def require_ok(self) -> None:
        """Raise the HardwareError matching a non-normal status."""
        from armstereo import errors

        st = self.status()
        kinds = {
            ArmState.PROTECTIVE_STOP: errors.ProtectiveStop,
            ArmState.EMERGENCY_STOP: errors.EmergencyStop,
            ArmState.DISCONNECTED: errors.ConnectionLost,
        }
        if not st.ok:
            raise kinds.get(st.state, HardwareError)(
                f"{self.name}: {st.state.value}" + (f" ({st.detail})" if st.detail else ""))


class Camera(Device):
    """A camera that delivers fresh frames on request."""

    name: str = "camera"

    @property
    @abstractmethod
    def intrinsics(self) -> Intrinsics:
        """Image size, K and distortion of the delivered images."""

    def recording_metadata(self) -> dict[str, str]:
        """What a recording should keep about this camera (str -> str), e.g. the settings it
        locked or, for a simulated camera, its scene's ground truth. Read after connect."""
        return {}

    @abstractmethod
    def grab(self, timeout: float = 2.0) -> Frame:
        """A frame exposed after this call began (stale buffers flushed); raises CameraTimeout."""
