"""The exposure, gain, white balance and gamma a camera took a frame with, and when two views
of a stereo pair differ by more than the matcher tolerates.

Cameras report what they know per frame (:attr:`armstereo.frame.Frame.settings`); recordings
keep it in each view event (``camera_settings``). Names carry their unit where the device
states one, so values from different backends are never confused:

==================  ==========================================================================
``exposure_us``     exposure time, microseconds (GenICam ``ExposureTime``)
``exposure``        exposure in the device's own unit (RealSense option units; the mock camera's
                    relative exposure, 1 = nominal)
``gain_db``         analogue/digital gain, decibels (GenICam ``Gain``)
``gain``            gain in the device's own unit (linear where it is a factor)
``white_balance_k`` white balance as a colour temperature, kelvin (RealSense)
``balance_ratio``   white balance as per-channel gains ``[red, green, blue]`` (GenICam
                    ``BalanceRatio``; the mock camera)
``gamma``           gamma exponent
==================  ==========================================================================

What the matcher tolerates (see docs/cameras.md, "Exposure that holds", and
bench/results/exposure_mismatch.md for the measurement): the Birchfield-Tomasi cost compares
raw intensities of the two views, so a brightness ratio between them is a cost the matcher pays
at every pixel. :data:`BRIGHTNESS_TOLERANCE` and :data:`WHITE_BALANCE_TOLERANCE` are the
relative differences up to which the measured disparity error stays within noise.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from armstereo.errors import RecordingError

SETTING_NAMES = ("exposure_us", "exposure", "gain_db", "gain", "white_balance_k",
                 "balance_ratio", "gamma")
# Relative brightness difference (exposure x gain) between the two views of a pair above which
# `check` warns. Measured (bench/results/exposure_mismatch.md): Birchfield-Tomasi's depth error
# is unchanged up to +0.25 % (the 8-bit views barely differ: a quarter of a grey level at mid
# grey) and rises by half at +0.5 %, on the tuning scene and the held-out one alike; SGBM, whose
# prefilter sees gradients, does not notice 10 %. A locked camera reports equal settings.
BRIGHTNESS_TOLERANCE = 0.0025
# Relative difference of any one colour channel's gain (relative to green), or of the colour
# temperature: one channel +0.5 % costs BT 10-13 % more depth error, +0.25 % nothing.
WHITE_BALANCE_TOLERANCE = 0.0025
# Relative gamma difference: it moves mid grey by ln(2) x d(gamma)/gamma, so this keeps mid
# grey within the brightness tolerance.
GAMMA_TOLERANCE = 0.0035


def validate(settings: Mapping[str, object] | None, what: str = "camera settings"
             ) -> dict[str, float | list[float]] | None:
    """``settings`` as JSON-ready values (finite floats, or lists of them for
    ``balance_ratio``); RecordingError naming the bad entry. None stays None."""
    if settings is None:
        return None
    if not isinstance(settings, Mapping):
        raise RecordingError(f"{what} must be a mapping of name -> number, got "
                             f"{type(settings).__name__}")
    out: dict[str, float | list[float]] = {}
    for name, value in settings.items():
        if name not in SETTING_NAMES:
            raise RecordingError(f"{what}: unknown setting {name!r} (known: "
                                 f"{', '.join(SETTING_NAMES)})")
        values = list(value) if isinstance(value, (list, tuple)) else [value]
        if not values or not all(_finite(v) for v in values):
            raise RecordingError(f"{what}: {name} must be finite number(s), got {value!r}")
        out[name] = [float(v) for v in values] if isinstance(value, (list, tuple)) \
            else float(values[0])
    return out


def view_event_fields(frame) -> dict:
    """The recording's view-event keys for what the camera reported about ``frame``
    (:class:`armstereo.frame.Frame`): ``camera_settings``, ``device_timestamp_ns`` and
    ``device_frame``, each only where reported. RecordingError for a malformed value."""
    out: dict = {}
    settings = validate(getattr(frame, "settings", None))
    if settings:
        out["camera_settings"] = settings
    for key in ("device_timestamp_ns", "device_frame"):
        value = getattr(frame, key, None)
        if value is None:
            continue
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 0:
            raise RecordingError(f"frame {key} must be an integer >= 0, got {value!r}")
        out[key] = int(value)
    return out


def _finite(v: object) -> bool:
    return (isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, bool)
            and math.isfinite(v))


@dataclass(frozen=True)
class SettingsDifference:
    """One way the two views of a pair differ: ``what`` (``brightness``, ``white balance``,
    ``gamma``), the relative difference, the tolerance, and which settings make it up."""

    what: str
    relative: float
    tolerance: float
    detail: str

    @property
    def too_large(self) -> bool:
        return self.relative > self.tolerance

    def describe(self) -> str:
        return (f"the two views differ in {self.what} by {self.relative * 100:.1f} % ({self.detail}"
                f"; more than {self.tolerance * 100:g} % costs the matcher accuracy)")

    def as_dict(self) -> dict:
        return {"what": self.what, "relative": round(self.relative, 5),
                "tolerance": self.tolerance, "detail": self.detail}


def compare(left: Mapping[str, object] | None, right: Mapping[str, object] | None
            ) -> list[SettingsDifference]:
    """How the settings of two views differ, for the settings both report (none when either
    reports nothing). Brightness combines exposure and gain (a longer exposure at a lower
    gain is the same image); white balance compares each channel's gain or the colour
    temperature. Each entry says whether it exceeds its tolerance (``too_large``)."""
    if not left or not right:
        return []
    out = []
    brightness = _brightness_ratio(left, right)
    if brightness is not None:
        ratio, parts = brightness
        out.append(SettingsDifference("brightness", abs(ratio - 1.0), BRIGHTNESS_TOLERANCE,
                                      parts))
    wb = _white_balance(left, right)
    if wb is not None:
        out.append(SettingsDifference("white balance", wb[0], WHITE_BALANCE_TOLERANCE, wb[1]))
    if "gamma" in left and "gamma" in right:
        rel = _relative(float(left["gamma"]), float(right["gamma"]))
        out.append(SettingsDifference("gamma", rel, GAMMA_TOLERANCE,
                                      f"gamma {left['gamma']:g} vs {right['gamma']:g}"))
    return out


def _brightness_ratio(a: Mapping, b: Mapping) -> tuple[float, str] | None:
    """right/left brightness factor from exposure and gain, and the settings behind it."""
    ratio, parts = 1.0, []
    for name in ("exposure_us", "exposure", "gain"):
        if name in a and name in b and float(a[name]) > 0 and float(b[name]) > 0:
            ratio *= float(b[name]) / float(a[name])
            parts.append(f"{name} {float(a[name]):g} vs {float(b[name]):g}")
    if "gain_db" in a and "gain_db" in b:
        ratio *= 10.0 ** ((float(b["gain_db"]) - float(a["gain_db"])) / 20.0)
        parts.append(f"gain_db {float(a['gain_db']):g} vs {float(b['gain_db']):g}")
    if not parts:
        return None
    return ratio, ", ".join(parts)


def _white_balance(a: Mapping, b: Mapping) -> tuple[float, str] | None:
    if "balance_ratio" in a and "balance_ratio" in b:
        ra, rb = list(a["balance_ratio"]), list(b["balance_ratio"])
        if len(ra) == len(rb) and ra:
            # the colour cast is what changes between the channels, not their common level
            # (that is brightness): compare each channel relative to the green one
            ga, gb = (ra[1], rb[1]) if len(ra) == 3 else (1.0, 1.0)
            rel = max(_relative(x / ga, y / gb) for x, y in zip(ra, rb, strict=True))
            text = (f"balance_ratio [{', '.join(f'{x:.3f}' for x in ra)}] vs "
                    f"[{', '.join(f'{y:.3f}' for y in rb)}]")
            return rel, text
    if "white_balance_k" in a and "white_balance_k" in b:
        ka, kb = float(a["white_balance_k"]), float(b["white_balance_k"])
        return _relative(ka, kb), f"white_balance_k {ka:g} vs {kb:g}"
    return None


def _relative(x: float, y: float) -> float:
    scale = max(abs(x), abs(y))
    return 0.0 if scale == 0 else abs(x - y) / scale
