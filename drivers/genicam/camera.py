"""GenICam camera backend: industrial GigE Vision / USB3 Vision cameras through ``harvesters``
and the vendor's GenTL producer (``genicam:<serial or index>``).

Connect: load the producer (:mod:`drivers.genicam.producer`), open the camera by serial number
or index, choose and set the pixel format (:mod:`drivers.genicam.pixels`), set the image size
to the intrinsics', lock exposure, gain, white balance and gamma (:mod:`drivers.genicam.features`),
switch on the per-frame chunks the camera offers, and arm the software trigger.

Fresh frames: with a software trigger, acquisition runs armed and every grab drops whatever is
queued, triggers once and waits for that frame; without one, acquisition is started for the
grab and stopped after it, so the frame was exposed after the call began, never taken from a
buffer filled while the arm moved.
"""

from __future__ import annotations

import json
import logging
from typing import TYPE_CHECKING

import numpy as np

from armstereo.camera_model import Intrinsics
from armstereo.clock import Clock, RealClock
from armstereo.devices import Camera, Frame
from armstereo.errors import CameraTimeout, ConfigError, ConnectionFailed, HardwareError
from drivers.genicam import features as F
from drivers.genicam import pixels, producer

if TYPE_CHECKING:
    from armstereo.devices import Arm
    from armstereo.kinematics import ArmModel
    from drivers.genicam.config import GenICamCameraConfig

log = logging.getLogger(__name__)

MAX_DRAIN = 64  # queued buffers dropped before a trigger, at most


class GenICamCamera(Camera):
    """One GenICam camera. ``device`` is its serial number or index; ``intrinsics`` the mount's
    (the camera's Width/Height are set to their size). ``cti``, ``exposure_us``, ``gain_db``,
    ``balance_ratio``, ``gamma``, ``pixel_format``, ``trigger`` and ``timeout`` as in
    :class:`drivers.genicam.config.GenICamCameraConfig`. ``clock`` stamps frames (the arm's).
    After connect, ``report`` holds what was locked and read back, ``trigger_mode`` is
    ``software`` or ``none``."""

    name = "genicam"

    def __init__(self, device: str, intrinsics: Intrinsics, *, cti: str | None = None,
                 exposure_us: float | None = None, gain_db: float | None = None,
                 balance_ratio: tuple[float, float, float] | None = None,
                 gamma: float | None = None, pixel_format: str | None = None,
                 trigger: str = "auto", timeout: float = 5.0, clock: Clock | None = None):
        self.device = str(device)
        self._intrinsics = intrinsics
        self.cti = cti
        self.wanted = dict(exposure_us=exposure_us, gain_db=gain_db,
                           balance_ratio=balance_ratio, gamma=gamma)
        self.pixel_format = pixel_format
        self.trigger = trigger
        self.timeout = float(timeout)
        self.clock = clock if clock is not None else RealClock()
        self.name = f"GenICam camera {self.device!r}"
        self.entry: producer.DeviceEntry | None = None
        self.report = F.FeatureReport()
        self.trigger_mode = "none"
        self.chunks: list[str] = []
        self._files: tuple[str, ...] = ()
        self._harvester = None
        self._ia = None
        self._nm = None

    @classmethod
    def from_config(cls, config: GenICamCameraConfig, model: ArmModel,
                    arm: Arm) -> GenICamCamera:
        """The registry's constructor: the mount's intrinsics (scaled to ``resolution`` if
        asked for) and the arm's clock."""
        intrinsics = model.mount.intrinsics
        if config.resolution is not None:
            intrinsics = intrinsics.scaled(*config.resolution)
        return cls(config.device, intrinsics, cti=config.cti, exposure_us=config.exposure_us,
                   gain_db=config.gain_db, balance_ratio=config.balance_ratio,
                   gamma=config.gamma, pixel_format=config.pixel_format,
                   trigger=config.trigger, timeout=config.timeout, clock=arm.clock)

    @property
    def intrinsics(self) -> Intrinsics:
        return self._intrinsics

    # ------------------------------------------------------------------------ life cycle
    def connect(self) -> None:
        """Open and configure the camera (module doc). ConfigError (exit 2) for a missing
        extra or producer, a pixel format, size or setting the camera cannot take;
        ConnectionFailed (exit 4) for an unknown serial or a camera in use."""
        self._require_not_connected()
        self._files = producer.producer_files(self.cti)
        self._harvester = producer.acquire(self._files)
        try:
            self.entry = producer.find(producer.devices(self._harvester), self.device,
                                       self._files)
            self.name = f"GenICam camera {self.entry.serial or self.device!r}"
            self._ia = self._open(self.entry)
            self._nm = self._ia.remote_device.node_map
            self._configure()
            if self.trigger_mode == "software":
                self._call(self._ia.start, "starting acquisition")
            self._connected = True
        except BaseException:
            self.close()
            raise

    def close(self) -> None:
        """Stop acquisition and release the camera and the producer. Idempotent."""
        ia, self._ia, self._nm, self._connected = self._ia, None, None, False
        if ia is not None:
            for step in (ia.stop, ia.destroy):
                try:
                    step()
                except Exception as err:  # noqa: BLE001 - closing must not raise
                    log.warning("%s: %s failed: %s", self.name, step.__name__, err)
        if self._harvester is not None:
            self._harvester = None
            producer.release(self._files)

    def recording_metadata(self) -> dict[str, str]:
        """The camera (serial, vendor, model, producer), the pixel format, the trigger, and
        the settings locked and read back at connect."""
        e = self.entry
        return {"camera_device": f"genicam:{self.device}",
                "camera_serial": e.serial if e else "", "camera_vendor": e.vendor if e else "",
                "camera_model": e.model if e else "",
                "camera_producer": ", ".join(self._files),
                "camera_pixel_format": self.pixel_format or "",
                "camera_trigger": self.trigger_mode,
                "camera_settings": json.dumps(self.report.settings, sort_keys=True),
                "camera_locked": ",".join(self.report.locked),
                "camera_missing_features": ",".join(self.report.missing),
                "camera_frame_chunks": ",".join(self.chunks)}

    # ----------------------------------------------------------------------------- grab
    def grab(self, timeout: float | None = None) -> Frame:
        """A frame exposed after this call began (module doc), stamped with the shared clock
        when the exposure was started (trigger sent, or acquisition started), with the
        camera's own time stamp, frame counter and settings. CameraTimeout after
        ``timeout`` s."""
        self._require_connected()
        timeout = self.timeout if timeout is None else float(timeout)
        if self.trigger_mode == "software":
            self._drain()
            t_ns = self.clock.now_ns()
            self._call(lambda: F.fire(self._nm, self.name), "triggering")
            return self._fetch(timeout, t_ns)
        t_ns = self.clock.now_ns()
        self._call(self._ia.start, "starting acquisition")
        try:
            return self._fetch(timeout, t_ns)
        finally:
            self._call(self._ia.stop, "stopping acquisition")

    def _fetch(self, timeout: float, t_ns: int) -> Frame:
        try:
            buffer = self._ia.fetch(timeout=timeout)
        except Exception as err:  # noqa: BLE001 - the producer's own exception types
            if type(err).__name__ == "TimeoutException":
                raise CameraTimeout(f"{self.name} delivered no frame within {timeout:g} s"
                                    + (" of the trigger" if self.trigger_mode == "software"
                                       else "")) from None
            raise HardwareError(f"{self.name}: fetching a frame failed: "
                                f"{producer._first_line(err)}") from None
        with buffer:
            image = self._image(buffer)
            stamp, frame_id = _buffer_time(buffer), _frame_id(buffer)
            chunk_settings, chunk_stamp = F.frame_chunks(self._nm, self.chunks)
        settings = {**self.report.settings, **F.read_settings(self._nm, balance=False),
                    **chunk_settings}
        return Frame(image, t_ns, settings=settings or None,
                     device_timestamp_ns=chunk_stamp if chunk_stamp is not None else stamp,
                     device_frame=frame_id)

    def _image(self, buffer) -> np.ndarray:
        comp = buffer.payload.components[0]
        fmt = str(comp.data_format)
        if not pixels.is_supported(fmt):
            raise ConfigError(f"{self.name} delivers pixel format {fmt!r}, which armstereo does "
                              f"not convert (supported: {', '.join(pixels.SUPPORTED)})")
        image = pixels.to_image(comp.data, int(comp.width), int(comp.height), fmt)
        want_w, want_h = self._intrinsics.size
        if image.shape[1] != want_w or image.shape[0] != want_h:
            raise HardwareError(f"{self.name} delivered a {image.shape[1]}x{image.shape[0]} "
                                f"frame; the intrinsics are for {want_w}x{want_h}")
        return image

    def _drain(self) -> None:
        """Drop frames already queued (none should be: each one waits for a trigger)."""
        for _ in range(MAX_DRAIN):
            buffer = self._ia.try_fetch(timeout=0.001)
            if buffer is None:
                return
            log.debug("%s: dropped a queued frame before the trigger", self.name)
            buffer.queue()

    # ------------------------------------------------------------------------ configure
    def _open(self, entry: producer.DeviceEntry):
        try:
            return self._harvester.create(entry.index)
        except Exception as err:  # noqa: BLE001 - the producer's own exception types
            kind = type(err).__name__
            if kind in ("ResourceInUseException", "AccessDeniedException", "BusyException"):
                raise ConnectionFailed(f"{self.name} is in use (open in another program, or "
                                       f"already in this one): close it there first") from None
            raise ConnectionFailed(f"cannot open {self.name}: {producer._first_line(err)}"
                                   ) from None

    def _configure(self) -> None:
        nm = self._nm
        self._set_pixel_format(nm)
        self._set_size(nm)
        self.report = F.lock_settings(nm, self.name, **self.wanted)
        self.trigger_mode = F.setup_trigger(nm, self.trigger, self.name)
        F.set_enum(nm, "AcquisitionMode", "Continuous")
        self.chunks = F.enable_frame_chunks(nm)
        log.info("%s (%s %s): %s, trigger %s, settings %s%s", self.name, self.entry.vendor,
                 self.entry.model, self.pixel_format, self.trigger_mode, self.report.settings,
                 f"; no {', '.join(self.report.missing)}" if self.report.missing else "")

    def _set_pixel_format(self, nm) -> None:
        n = F.node(nm, "PixelFormat")
        if n is None:
            raise ConfigError(f"{self.name} has no PixelFormat feature")
        chosen = pixels.choose(F.symbolics(n), self.pixel_format, self.name)
        if n.value != chosen:
            if not F.writable(n):
                raise ConfigError(f"{self.name}: PixelFormat is read-only ({n.value})")
            n.value = chosen
        self.pixel_format = chosen

    def _set_size(self, nm) -> None:
        want_w, want_h = self._intrinsics.size
        for offset in ("OffsetX", "OffsetY"):
            n = F.node(nm, offset)
            if F.writable(n) and n.value != 0:
                n.value = 0
        for name, want in (("Width", want_w), ("Height", want_h)):
            n = F.node(nm, name)
            if n is None:
                raise ConfigError(f"{self.name} has no {name} feature")
            if n.value == want:
                continue
            lo, hi, inc = int(n.min), int(n.max), max(1, int(getattr(n, "inc", 1) or 1))
            if not F.writable(n):
                why = f"{name} is read-only at {n.value}"
            elif not lo <= want <= hi or (want - lo) % inc:
                why = f"{name} takes {lo}..{hi} in steps of {inc}"
            else:
                n.value = want
                continue
            raise ConfigError(f"{self.name} cannot deliver {want_w}x{want_h} images ({why}): "
                              "give --resolution in a mode it has, with the mount's aspect "
                              "ratio")

    def _call(self, fn, what: str):
        try:
            return fn()
        except Exception as err:  # noqa: BLE001 - the producer's own exception types
            raise HardwareError(f"{self.name}: {what} failed: {producer._first_line(err)}"
                                ) from None


def _buffer_time(buffer) -> int | None:
    """The producer's time stamp of the buffer in ns (None when it gives none: 0 or absent)."""
    try:
        ns = int(buffer.timestamp_ns)
        if ns > 0:
            return ns
    except Exception:  # noqa: BLE001 - GenTL NotAvailable: the producer keeps no time stamps
        pass
    try:
        ticks, hz = int(buffer.timestamp), int(buffer.timestamp_frequency)
    except Exception:  # noqa: BLE001
        return None
    if ticks <= 0 or hz <= 0:
        return None
    return ticks * 1_000_000_000 // hz


def _frame_id(buffer) -> int | None:
    try:
        value = int(buffer.module.frame_id)
    except Exception:  # noqa: BLE001 - optional GenTL buffer info
        return None
    return value if value >= 0 else None
