"""RealSense camera backend: the colour sensor of an Intel RealSense camera
(``realsense:<serial>``), live or played back from an SDK recording.

Connect: find the camera by serial (or load the recording and check its serial), choose the
colour mode (:func:`drivers.realsense.settings.choose_profile`), lock exposure, gain and white
balance, read the factory intrinsics, start streaming into a one-frame slot.

Fresh frames: a live camera streams continuously; a grab waits for the first frame exposed
after the call began: one whose host-synchronised time stamp (global or system time domain) is
not earlier than the call, or, when the camera has only its own clock, the second frame to
arrive after the call (the first may have been exposing while the arm still moved). A playback
runs without real time: it hands over its frames one by one, each grab the next one, so a
recorded capture replays shot for shot.
"""

from __future__ import annotations

import json
import logging
import threading
import time
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from armstereo.camera_model import Intrinsics
from armstereo.clock import Clock, RealClock
from armstereo.devices import Camera, Frame
from armstereo.errors import CameraTimeout, ConfigError, ConnectionFailed, HardwareError
from armstereo.mount import DEFAULT_MOUNT
from drivers.realsense import sdk
from drivers.realsense import settings as S

if TYPE_CHECKING:
    from armstereo.devices import Arm
    from armstereo.kinematics import ArmModel
    from drivers.realsense.config import RealSenseCameraConfig

log = logging.getLogger(__name__)


@dataclass
class _Shot:
    """A frame as the SDK's thread hands it over: a copy of its pixels and what it says."""

    image: np.ndarray
    arrived_ns: int  # host wall clock
    host_stamp_ns: int | None  # the frame's time stamp when host-synchronised
    settings: dict
    device_ns: int | None
    number: int | None


class _Slot:
    """Where the SDK's callback puts frames. Live: the latest frame replaces the last one.
    Playback (``hold``): the callback waits until the frame is taken, so none is dropped."""

    def __init__(self, hold: bool):
        self.hold = hold
        self._cond = threading.Condition()
        self._shots: list[_Shot] = []
        self._closed = False

    def put(self, shot: _Shot) -> None:
        with self._cond:
            if self.hold:
                while self._shots and not self._closed:
                    self._cond.wait(0.1)
                if self._closed:
                    return
            self._shots = [shot]
            self._cond.notify_all()

    def take(self, accept, deadline: float) -> _Shot | None:
        """The first frame ``accept`` takes before ``deadline`` (monotonic s), or None."""
        with self._cond:
            while True:
                while self._shots:
                    shot = self._shots.pop(0)
                    self._cond.notify_all()
                    if accept(shot):
                        return shot
                left = deadline - time.monotonic()
                if left <= 0 or self._closed:
                    return None
                self._cond.wait(min(left, 0.1))

    def close(self) -> None:
        with self._cond:
            self._closed = True
            self._cond.notify_all()


class RealSenseCamera(Camera):
    """The colour stream of RealSense camera ``serial`` (or of the recording ``playback``).
    ``mount_intrinsics``: the mount's; ``intrinsics_source`` decides which intrinsics are
    delivered (see :class:`drivers.realsense.config.RealSenseCameraConfig`); ``resolution``,
    ``fps``, ``exposure``, ``gain``, ``white_balance``, ``timeout`` as there. ``device``: an
    ``rs.device`` to use instead of looking the serial up (a software device in tests)."""

    name = "realsense"

    def __init__(self, serial: str, mount_intrinsics: Intrinsics, *, playback: str | None = None,
                 intrinsics_source: str = "device", resolution: tuple[int, int] | None = None,
                 fps: int = 30, exposure: float | None = None, gain: float | None = None,
                 white_balance: float | None = None, timeout: float = 5.0,
                 clock: Clock | None = None, device=None):
        self.serial = str(serial)
        self.mount_intrinsics = mount_intrinsics
        self.playback = playback
        self.intrinsics_source = intrinsics_source
        self.resolution, self.fps = resolution, int(fps)
        self.wanted = dict(exposure=exposure, gain=gain, white_balance=white_balance)
        self.timeout = float(timeout)
        self.clock = clock if clock is not None else RealClock()
        self.name = f"RealSense {self.serial}"
        self._given_device = device
        self._device = self._sensor = self._slot = None
        self._intrinsics: Intrinsics | None = None
        self.mode: S.Mode | None = None
        self.locked = S.Locked()
        self.device_info: dict[str, str] = {}
        self.intrinsics_note = ""
        self.intrinsics_disagreement: list[str] = []
        self._period_ns = 0

    @classmethod
    def from_config(cls, config: RealSenseCameraConfig, model: ArmModel,
                    arm: Arm) -> RealSenseCamera:
        """The registry's constructor on the arm's clock. ``intrinsics=auto`` takes the
        device's unless the mount is a file of the user's (not the bundled default)."""
        source = config.intrinsics
        if source == "auto":
            source = "device" if model.mount.name == DEFAULT_MOUNT else "mount"
        return cls(config.device, model.mount.intrinsics, playback=config.playback,
                   intrinsics_source=source, resolution=config.resolution, fps=config.fps,
                   exposure=config.exposure, gain=config.gain,
                   white_balance=config.white_balance, timeout=config.timeout, clock=arm.clock)

    @property
    def intrinsics(self) -> Intrinsics:
        """The delivered images' intrinsics (known after connect: the device's factory
        calibration, or the mount's)."""
        if self._intrinsics is None:
            raise ConfigError(f"{self.name}: the intrinsics are known once it is connected")
        return self._intrinsics

    # ------------------------------------------------------------------------ life cycle
    def connect(self) -> None:
        """Open, configure and start the colour stream (module doc). ConfigError (exit 2)
        for a missing extra, a mode or setting the camera lacks; ConnectionFailed (exit 4)
        for an unknown serial or a camera in use."""
        self._require_not_connected()
        rs = sdk.rs()
        try:
            self._device = self._find(rs)
            self.device_info = S.device_info(rs, self._device)
            self.name = f"{self.device_info.get('name') or 'RealSense'} {self.serial}"
            self._sensor = self._colour_sensor(rs)
            preferred = self.mount_intrinsics.size if self.resolution is None else None
            if self.resolution is None and self.intrinsics_source == "mount":
                self.resolution = self.mount_intrinsics.size
            profile = S.choose_profile(rs, S.colour_profiles(rs, self._sensor),
                                       self.resolution, self.fps, preferred, self.name)
            self.mode = S.mode_of(rs, profile)
            self._period_ns = int(1e9 / max(1, self.mode.fps))
            self._set_intrinsics(rs, profile)
            self.locked = S.lock_options(rs, self._sensor, self.name, **self.wanted)
            self._start(rs, profile)
            self._connected = True
        except BaseException:
            self.close()
            raise

    def close(self) -> None:
        """Stop the stream and release the camera. Idempotent; never raises."""
        sensor, slot = self._sensor, self._slot
        self._sensor = self._slot = self._device = None
        self._connected = False
        if slot is not None:
            slot.close()  # a playback callback waiting for its frame to be taken lets go
        if sensor is not None:
            for step in ("stop", "close"):
                try:
                    getattr(sensor, step)()
                except Exception as err:  # noqa: BLE001 - closing must not raise
                    log.debug("%s: %s: %s", self.name, step, sdk.error_text(err))

    def recording_metadata(self) -> dict[str, str]:
        """The camera (name, serial, firmware), the colour mode, where the intrinsics come
        from, how the mount's disagree with the device's, and the settings locked."""
        return {"camera_device": f"realsense:{self.serial}",
                "camera_serial": self.serial, "camera_model": self.device_info.get("name", ""),
                "camera_firmware": self.device_info.get("firmware", ""),
                "camera_playback": self.playback or "",
                "camera_mode": self.mode.label() if self.mode else "",
                "camera_intrinsics_source": self.intrinsics_source,
                "camera_intrinsics_note": self.intrinsics_note,
                "camera_intrinsics_vs_mount": "; ".join(self.intrinsics_disagreement),
                "camera_settings": json.dumps(self.locked.settings, sort_keys=True),
                "camera_locked": ",".join(self.locked.auto_off),
                "camera_notes": "; ".join(self.locked.notes)}

    # ----------------------------------------------------------------------------- grab
    def grab(self, timeout: float | None = None) -> Frame:
        """A frame exposed after this call began (live), or the recording's next frame
        (playback); CameraTimeout after ``timeout`` s (a playback at its end, too)."""
        self._require_connected()
        timeout = self.timeout if timeout is None else float(timeout)
        t_ns = self.clock.now_ns()
        called = time.time_ns()
        shot = self._slot.take(self._accept(called), time.monotonic() + timeout)
        if shot is None:
            end = " (the recording has no more frames?)" if self.playback else ""
            raise CameraTimeout(f"{self.name} delivered no fresh frame within {timeout:g} s"
                                f"{end}")
        if self._slot.hold:
            t_ns = self.clock.now_ns()
        return Frame(shot.image, t_ns, settings=shot.settings or None,
                     device_timestamp_ns=shot.device_ns, device_frame=shot.number)

    def _accept(self, called_ns: int):
        if self._slot.hold:
            return lambda shot: True
        seen = []

        def fresh(shot: _Shot) -> bool:
            if shot.host_stamp_ns is not None:
                return shot.host_stamp_ns >= called_ns
            if shot.arrived_ns < called_ns:
                return False
            seen.append(shot)
            return len(seen) >= 2  # the first one may have been exposing before the call

        return fresh

    # ------------------------------------------------------------------------ internals
    def _find(self, rs):
        if self._given_device is not None:
            return self._given_device
        ctx = rs.context()
        if self.playback is not None:
            try:
                device = ctx.load_device(str(self.playback))
            except RuntimeError as err:
                raise ConfigError(f"--realsense-playback {self.playback}: not a RealSense "
                                  f"recording the SDK reads ({sdk.error_text(err)})") from None
            device.as_playback().set_real_time(False)
            recorded = S.device_info(rs, device).get("serial", "")
            if recorded != self.serial:
                raise ConnectionFailed(f"the recording {self.playback} is of RealSense "
                                       f"{recorded!r}, not {self.serial!r}")
            return device
        found = []
        for device in ctx.query_devices():
            info = S.device_info(rs, device)
            if info.get("serial") == self.serial:
                return device
            found.append(f"{info.get('serial', '?')} ({info.get('name', '')})")
        raise ConnectionFailed(f"no RealSense camera with serial {self.serial!r} (found: "
                               f"{', '.join(found) or 'none'}; is it plugged in, on USB 3?)")

    def _colour_sensor(self, rs):
        for sensor in self._device.query_sensors():
            if S.colour_profiles(rs, sensor):
                return sensor
        raise ConfigError(f"{self.name} has no colour stream")

    def _set_intrinsics(self, rs, profile) -> None:
        device, self.intrinsics_note = S.to_intrinsics(rs, profile.get_intrinsics())
        mount = self.mount_intrinsics
        if self.intrinsics_source == "device":
            self._intrinsics = device
            return
        if mount.size != device.size:
            mount = mount.scaled(*device.size)
        self.intrinsics_disagreement = S.cross_check(device, mount)
        for line in self.intrinsics_disagreement:
            log.warning("%s: the mount's intrinsics differ from the factory calibration: %s",
                        self.name, line)
        self._intrinsics = mount

    def _start(self, rs, profile) -> None:
        self._slot = _Slot(hold=self.playback is not None)
        rgb = self.mode.format == "rgb8"
        host_domains = (rs.timestamp_domain.global_time, rs.timestamp_domain.system_time)

        def on_frame(frame) -> None:  # the SDK's thread
            try:
                image = np.array(np.asanyarray(frame.get_data()), copy=True)
                if rgb:
                    image = np.ascontiguousarray(image[..., ::-1])
                settings, device_ns, number = S.frame_report(rs, frame)
                host = int(frame.get_timestamp() * 1e6) \
                    if frame.get_frame_timestamp_domain() in host_domains else None
                self._slot.put(_Shot(image, time.time_ns(), host, settings, device_ns, number))
            except Exception as err:  # noqa: BLE001 - never let an exception into the SDK
                log.warning("%s: dropped a frame: %s", self.name, sdk.error_text(err))

        try:
            self._sensor.open(profile)
            self._sensor.start(on_frame)
        except RuntimeError as err:
            text = sdk.error_text(err)
            if "busy" in text.lower() or "in use" in text.lower():
                raise ConnectionFailed(f"{self.name} is in use by another program") from None
            raise HardwareError(f"{self.name}: starting the colour stream failed: {text}"
                                ) from None

