"""Config of the GenICam camera backend (registry name ``genicam:<serial or index>``); its
fields' metadata are the command-line flags. Importing it needs no extra installed."""

from __future__ import annotations

from dataclasses import dataclass, field

from armstereo.errors import ConfigError
from armstereo.flags import option
from armstereo.validate import number, positive
from drivers.opencv.config import parse_resolution

TRIGGER_MODES = ("auto", "software", "off")
MAX_EXPOSURE_US = 10_000_000.0  # 10 s: beyond any stop-and-shoot exposure


def parse_ratio(text: str | tuple | None) -> tuple[float, float, float] | None:
    """``--balance-ratio R,G,B`` as three positive numbers; None stays None."""
    if text is None:
        return None
    items = text.split(",") if isinstance(text, str) else list(text)
    if len(items) != 3:
        raise ConfigError(f"--balance-ratio must be three numbers R,G,B, got {text!r}")
    return tuple(positive(v, "--balance-ratio", "") for v in items)


@dataclass(frozen=True, kw_only=True)
class GenICamCameraConfig:
    """A GenICam camera (GigE Vision, USB3 Vision, ...) through a GenTL producer.

    ``device``: the camera's serial number, or its index in the producer's list (``armstereo
    cameras`` shows both). ``cti``: the producer (.cti file or folder); None: the folders in
    ``GENICAM_GENTL64_PATH``. ``exposure_us``, ``gain_db``, ``balance_ratio`` (red, green,
    blue) and ``gamma`` are set through the SFNC features and locked (automatic modes off);
    None keeps and locks what the camera uses now. ``pixel_format``: a PFNC name (default: the
    best the camera offers, colour first). ``resolution`` (width, height): the image size to
    set (the mount's intrinsics are scaled to it); default the mount's size. ``trigger``:
    ``auto`` uses a software trigger where the camera has one, ``software`` insists on it,
    ``off`` restarts acquisition for every shot instead.
    """

    device: str
    cti: str | None = field(default=None, metadata=option(
        "--cti", "GenICam camera: the GenTL producer (.cti file or folder) from the camera's "
        "vendor (default: the folders in GENICAM_GENTL64_PATH)", metavar="PATH"))
    exposure_us: float | None = field(default=None, metadata=option(
        "--exposure-us", "GenICam camera: ExposureTime in microseconds, locked (default: keep "
        "the camera's, auto exposure off)", type=float))
    gain_db: float | None = field(default=None, metadata=option(
        "--gain-db", "GenICam camera: Gain (SFNC, dB on most cameras), locked", type=float))
    balance_ratio: tuple[float, float, float] | None = field(default=None, metadata=option(
        "--balance-ratio", "GenICam camera: white balance as BalanceRatio red,green,blue, "
        "locked", metavar="R,G,B"))
    gamma: float | None = field(default=None, metadata=option(
        "--gamma", "GenICam camera: Gamma, locked", type=float))
    pixel_format: str | None = field(default=None, metadata=option(
        "--pixel-format", "GenICam camera: PFNC pixel format (Mono8/10/12/16, Bayer*8/10/12, "
        "RGB8, BGR8; default: the best the camera offers)"))
    resolution: tuple[int, int] | None = field(default=None, metadata=option(
        "--resolution", "OpenCV, GenICam or RealSense camera: WIDTHxHEIGHT to ask for "
        "(intrinsics are scaled to it)", metavar="WxH"))
    trigger: str = field(default="auto", metadata=option(
        "--trigger", "GenICam camera: auto (software trigger where the camera has one), "
        "software (insist), off (restart acquisition per shot)", choices=TRIGGER_MODES))
    timeout: float = 5.0

    def __post_init__(self) -> None:
        if not str(self.device).strip():
            raise ConfigError("the GenICam camera needs a serial number or index: "
                              "genicam:<serial or index> (armstereo cameras lists them)")
        object.__setattr__(self, "device", str(self.device).strip())
        if self.exposure_us is not None:
            positive(self.exposure_us, "--exposure-us", "us", cap=MAX_EXPOSURE_US)
        if self.gain_db is not None:
            number(self.gain_db, "--gain-db")  # its range is the camera's (read at connect)
        if self.gamma is not None:
            positive(self.gamma, "--gamma", "")
        object.__setattr__(self, "balance_ratio", parse_ratio(self.balance_ratio))
        object.__setattr__(self, "resolution", parse_resolution(self.resolution))
        if self.trigger not in TRIGGER_MODES:
            raise ConfigError(f"--trigger must be one of {', '.join(TRIGGER_MODES)}, got "
                              f"{self.trigger!r}")
        positive(self.timeout, "camera timeout", "s")
