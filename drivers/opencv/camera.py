"""A USB or GStreamer camera through OpenCV's VideoCapture, with exposure, gain and white
balance locked for the whole capture.

Why locked: the stereo matcher (Birchfield-Tomasi) compares raw intensities between the two
views of a pair, so auto exposure or auto white balance that changes between shots breaks it.

Every VideoCapture call runs on one worker thread (VideoCapture is not thread-safe, and grab()
can block for seconds on a stalled device) while the caller waits with a deadline; a device
that delivers nothing in time gives CameraTimeout naming it. Images are returned as OpenCV
delivers them (BGR for colour devices).
"""

from __future__ import annotations

import json
import logging
import time
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import cv2
import numpy as np

from armstereo.camera_model import Intrinsics
from armstereo.clock import Clock, RealClock
from armstereo.devices import Arm, Camera, Frame
from armstereo.errors import CameraTimeout, ConfigError, ConnectionFailed, HardwareError
from armstereo.validate import positive
from drivers.worker import DeadlineMissed, SerialWorker

if TYPE_CHECKING:
    from armstereo.robot.arm_model import ArmModel
    from drivers.opencv.config import OpenCVCameraConfig

log = logging.getLogger(__name__)

BACKENDS = {
    "any": cv2.CAP_ANY, "v4l2": cv2.CAP_V4L2, "gstreamer": cv2.CAP_GSTREAMER,
    "ffmpeg": cv2.CAP_FFMPEG, "dshow": cv2.CAP_DSHOW, "msmf": cv2.CAP_MSMF,
    "avfoundation": cv2.CAP_AVFOUNDATION,
}
# CAP_PROP_AUTO_EXPOSURE "off": V4L2 takes the raw V4L2 menu value (1 = manual); DirectShow and
# OpenCV's legacy normalised convention use 0.25 (0.75 = auto).
V4L2_MANUAL_EXPOSURE = 1.0
LEGACY_MANUAL_EXPOSURE = 0.25
GRAB_RETRY_S = 0.005      # pause after a failed grab before trying again
READ_GRACE_S = 0.5        # extra wait for a read job that is past its own deadline
SETTING_REL_TOL = 0.01    # read-back within 1 % (drivers round exposure to their steps)


class OpenCVCamera(Camera):
    """A camera opened by index (``0``), path (``/dev/video0``) or GStreamer pipeline.

    ``intrinsics``: the mount's calibration; the device must deliver exactly its size.
    ``timeout``: seconds to wait for a frame (connect and each grab). ``flush_frames``: frames
    grabbed and discarded before each kept frame, so buffered stale frames never reach the
    caller (V4L2 buffers 4). ``exposure``, ``gain``, ``white_balance`` (Kelvin): values in the
    backend's units; None keeps the device's current value, locked. ``backend``: a name from
    :data:`BACKENDS`, an OpenCV ``CAP_*`` id, or None (GStreamer for pipelines, else any).
    ``clock``: frame timestamps (default RealClock; pass the arm's clock to share it).
    After connect, ``settings`` holds the values the device reads back.
    """

    name = "opencv"

    def __init__(self, device: int | str, intrinsics: Intrinsics, *, timeout: float = 2.0,
                 flush_frames: int = 4, exposure: float | None = None, gain: float | None = None,
                 white_balance: float | None = None, backend: str | int | None = None,
                 clock: Clock | None = None):
        if isinstance(device, str) and device.strip().isdigit():
            device = int(device)
        if not isinstance(device, int | str) or (isinstance(device, str) and not device.strip()):
            raise ConfigError(f"camera device must be an index, a path or a pipeline, "
                              f"got {device!r}")
        positive(timeout, "camera timeout", "s")
        if not isinstance(flush_frames, int) or flush_frames < 0:
            raise ConfigError(f"flush_frames must be an integer >= 0, got {flush_frames!r}")
        self.device = device
        self._intrinsics = intrinsics
        self.timeout = float(timeout)
        self.flush_frames = flush_frames
        self.exposure, self.gain, self.white_balance = exposure, gain, white_balance
        self.api = _resolve_backend(backend, device)
        self.clock = clock if clock is not None else RealClock()
        self.name = f"camera {device!r}"
        self.settings: dict[str, float] = {}
        self._cap = None
        self._worker: SerialWorker | None = None

    @classmethod
    def from_config(cls, config: OpenCVCameraConfig, model: ArmModel, arm: Arm) -> OpenCVCamera:
        """The registry's constructor: the mount's intrinsics (scaled to ``resolution`` if one
        is asked for) and the arm's clock."""
        intrinsics = model.mount.intrinsics
        if config.resolution is not None:
            intrinsics = intrinsics.scaled(*config.resolution)
        device = int(config.device) if str(config.device).isdigit() else config.device
        return cls(device, intrinsics, timeout=config.timeout, exposure=config.exposure,
                   gain=config.gain, white_balance=config.white_balance,
                   backend=config.backend, clock=arm.clock)

    def recording_metadata(self) -> dict[str, str]:
        """The device and the exposure, gain and white balance it locked (read back)."""
        return {"camera_device": str(self.device),
                "camera_settings": json.dumps(self.settings, sort_keys=True)}

    @property
    def intrinsics(self) -> Intrinsics:
        return self._intrinsics

    def connect(self) -> None:
        """Open the device, set and check the image size, lock exposure/gain/white balance.

        Raises ConnectionFailed (won't open, or no first frame within ``timeout``), ConfigError
        (the device delivers another size than the intrinsics).
        """
        self._require_not_connected()
        self._worker = SerialWorker(f"opencv-{self.device}")
        try:
            self._cap = self._on_worker(self._open, self.timeout, "opening")
            if self._cap is None:
                raise ConnectionFailed(
                    f"cannot open camera {self.device!r} ({_backend_label(self.api)}): check the "
                    f"index or path and that no other program is using it")
            first = self._read(0, self.timeout)
            if first is None:
                raise ConnectionFailed(f"camera {self.device!r} opened but delivered no frame "
                                       f"within {self.timeout:g} s")
            problem = self._size_problem(first[0])
            if problem:
                raise ConfigError(f"camera {self.device!r} {problem}: choose a mount whose "
                                  f"intrinsics match the device's mode, or another device")
            self._on_worker(self._lock_settings, self.timeout, "locking exposure")
            self._connected = True
        except BaseException:
            self.close()
            raise

    def close(self) -> None:
        """Release the device (after any read in flight returns). Idempotent."""
        worker, cap = self._worker, self._cap
        self._worker, self._cap, self._connected = None, None, False
        if worker is None:
            return
        if cap is not None:
            try:
                worker.call(cap.release, timeout=self.timeout)
            except DeadlineMissed:
                log.warning("%s: still blocked in a read; it is released when that returns",
                            self.name)
            except Exception as err:  # noqa: BLE001 - closing must not raise
                log.warning("%s: release failed: %s", self.name, err)
        worker.close()

    def grab(self, timeout: float | None = None) -> Frame:
        """A frame grabbed after this call began: ``flush_frames`` buffered frames are discarded
        first. ``timestamp_ns`` is the clock at the moment the kept frame was grabbed.
        Raises CameraTimeout naming the device after ``timeout`` s (default: the constructor's)."""
        self._require_connected()
        timeout = self.timeout if timeout is None else timeout
        positive(timeout, "grab timeout", "s")
        got = self._read(self.flush_frames, timeout)
        if got is None:
            raise CameraTimeout(f"camera {self.device!r} delivered no frame within {timeout:g} s")
        image, t_ns = got
        problem = self._size_problem(image)
        if problem:
            raise HardwareError(f"camera {self.device!r} {problem} (changed since connect)")
        return Frame(image, t_ns)

    # ------------------------------------------------------------------ worker-thread jobs
    def _open(self):
        if not log.isEnabledFor(logging.DEBUG):
            # a failed open is reported by our own one-line error; OpenCV's backend probing
            # warnings (e.g. FFMPEG "should be configured with libavdevice") only confuse
            cv2.utils.logging.setLogLevel(cv2.utils.logging.LOG_LEVEL_ERROR)
        cap = cv2.VideoCapture(self.device, self.api)
        if not cap.isOpened():
            cap.release()
            return None
        width, height = self._intrinsics.size
        cap.set(cv2.CAP_PROP_FRAME_WIDTH, width)
        cap.set(cv2.CAP_PROP_FRAME_HEIGHT, height)
        cap.set(cv2.CAP_PROP_BUFFERSIZE, 1)  # fewer stale frames where the backend allows it
        return cap

    def _read(self, flush: int, timeout: float) -> tuple[np.ndarray, int] | None:
        """(image, timestamp_ns) grabbed within ``timeout`` s after ``flush`` discards, or None."""
        deadline = time.monotonic() + timeout
        try:
            return self._worker.call(self._read_job, flush, deadline,
                                     timeout=timeout + READ_GRACE_S)
        except DeadlineMissed:
            return None

    def _read_job(self, flush: int, deadline: float) -> tuple[np.ndarray, int] | None:
        cap = self._cap
        for _ in range(flush):
            cap.grab()
            if time.monotonic() > deadline:
                return None
        while time.monotonic() <= deadline:
            if cap.grab():
                t_ns = self.clock.now_ns()
                ok, image = cap.retrieve()
                if ok and image is not None:
                    return image, t_ns
            time.sleep(GRAB_RETRY_S)  # a failing device answers at once: don't spin
        return None

    def _lock_settings(self) -> None:
        """Auto exposure and auto white balance off; exposure, gain and white balance pinned
        (to the given values, or to what the device uses now). Read back; warn if ignored."""
        try:
            backend = self._cap.getBackendName()
        except cv2.error:
            backend = ""
        manual = V4L2_MANUAL_EXPOSURE if backend == "V4L2" else LEGACY_MANUAL_EXPOSURE
        self._apply("auto_exposure", cv2.CAP_PROP_AUTO_EXPOSURE, manual)
        self._apply("exposure", cv2.CAP_PROP_EXPOSURE, self.exposure)
        self._apply("gain", cv2.CAP_PROP_GAIN, self.gain)
        self._apply("auto_white_balance", cv2.CAP_PROP_AUTO_WB, 0.0)
        self._apply("white_balance", cv2.CAP_PROP_WB_TEMPERATURE, self.white_balance)
        log.info("%s locked: %s", self.name,
                 ", ".join(f"{k}={v:g}" for k, v in self.settings.items()))

    def _apply(self, setting: str, prop: int, value: float | None) -> None:
        cap = self._cap
        wanted = float(cap.get(prop) if value is None else value)
        accepted = bool(cap.set(prop, wanted))
        got = float(cap.get(prop))
        self.settings[setting] = got
        if not accepted or abs(got - wanted) > SETTING_REL_TOL * max(abs(wanted), 1e-9):
            log.warning("%s ignored %s = %g (reads back %g): image brightness or colour may "
                        "differ between the views of a pair", self.name, setting, wanted, got)

    # --------------------------------------------------------------------------- helpers
    def _on_worker(self, fn: Callable[[], Any], timeout: float, what: str) -> Any:
        try:
            return self._worker.call(fn, timeout=timeout + READ_GRACE_S)
        except DeadlineMissed:
            raise ConnectionFailed(f"camera {self.device!r} did not respond within {timeout:g} s "
                                   f"while {what}") from None

    def _size_problem(self, image: np.ndarray) -> str | None:
        height, width = image.shape[:2]
        want_w, want_h = self._intrinsics.size
        if (width, height) != (want_w, want_h):
            return (f"delivers {width}x{height} images but the intrinsics are for "
                    f"{want_w}x{want_h}")
        return None


def _resolve_backend(backend: str | int | None, device: int | str) -> int:
    if backend is None:
        return cv2.CAP_GSTREAMER if isinstance(device, str) and "!" in device else cv2.CAP_ANY
    if isinstance(backend, int):
        return backend
    key = str(backend).lower()
    if key not in BACKENDS:
        raise ConfigError(f"unknown OpenCV backend {backend!r}; choose one of: "
                          f"{', '.join(BACKENDS)}")
    return BACKENDS[key]


def _backend_label(api: int) -> str:
    names = {v: k for k, v in BACKENDS.items()}
    return f"backend {names.get(api, api)}"
