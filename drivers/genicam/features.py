"""Exposure, gain, white balance, gamma and trigger of a GenICam camera through their standard
feature names (SFNC), on a GenApi node map (``genicam.genapi.NodeMap``, what harvesters gives
as ``remote_device.node_map``).

Locking follows SFNC: the ``*Auto`` feature off first (``ExposureAuto``, ``GainAuto``,
``BalanceWhiteAuto``), then the value set (``ExposureTime`` in microseconds, ``Gain`` under
``GainSelector = All`` where the camera has it, ``BalanceRatio`` under ``BalanceRatioSelector``
Red/Green/Blue, ``Gamma`` with ``GammaEnable``), then read back. A value the user asked for that
the camera lacks or refuses is a ConfigError naming the feature and its range; one nobody asked
for is only read back (and locked where an ``*Auto`` switch exists).

The software trigger: ``TriggerSelector = FrameStart`` (where selectable), ``TriggerMode = On``,
``TriggerSource = Software``, one ``TriggerSoftware`` command per shot.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field

from armstereo.errors import ConfigError, HardwareError

log = logging.getLogger(__name__)

# genicam.genapi.EAccessMode values (NI, NA, WO, RO, RW); kept here so this module can be
# imported and its logic reasoned about without the extra installed.
_NOT_IMPLEMENTED, _NOT_AVAILABLE, _WRITE_ONLY, _READ_ONLY, _READ_WRITE = range(5)
BALANCE_CHANNELS = ("Red", "Green", "Blue")
# Chunks that carry per-frame settings and the device's time stamp (SFNC chunk names).
FRAME_CHUNKS = ("ExposureTime", "Gain", "Timestamp")
SET_REL_TOL = 0.01  # a read-back within 1 % of the value asked for (cameras round to steps)


@dataclass
class FeatureReport:
    """What :func:`lock_settings` did: ``settings`` read back (armstereo.camera_settings
    names), ``locked`` the ``*Auto`` switches turned off, ``missing`` standard features the
    camera lacks, ``notes`` anything else worth recording."""

    settings: dict[str, float | list[float]] = field(default_factory=dict)
    locked: list[str] = field(default_factory=list)
    missing: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)


def node(nm, name: str):
    """The node ``name`` of ``nm`` if the camera implements it and it is available now."""
    try:
        if not nm.has_node(name):
            return None
        n = nm.get_node(name)
        return n if n.get_access_mode() not in (_NOT_IMPLEMENTED, _NOT_AVAILABLE) else None
    except Exception:  # noqa: BLE001 - a node that cannot even be queried is as good as absent
        return None


def readable(n) -> bool:
    return n is not None and n.get_access_mode() in (_READ_ONLY, _READ_WRITE)


def writable(n) -> bool:
    return n is not None and n.get_access_mode() in (_WRITE_ONLY, _READ_WRITE)


def symbolics(n) -> tuple[str, ...]:
    """The entries an enumeration node offers now (empty for another node)."""
    try:
        return tuple(n.symbolics)
    except Exception:  # noqa: BLE001
        return ()


def set_enum(nm, name: str, value: str) -> bool:
    """Set enumeration ``name`` to ``value`` where the camera has and accepts it."""
    n = node(nm, name)
    if not writable(n) or value not in symbolics(n):
        return False
    n.value = value
    return True


def lock_settings(nm, camera: str, *, exposure_us: float | None, gain_db: float | None,
                  balance_ratio: tuple[float, float, float] | None,
                  gamma: float | None) -> FeatureReport:
    """Turn automatic exposure, gain and white balance off, set what was asked for, and read
    everything back (see the module doc). ``camera`` names it in errors."""
    rep = FeatureReport()
    _auto_off(nm, "ExposureAuto", rep)
    set_enum(nm, "ExposureMode", "Timed")
    _set_float(nm, "ExposureTime", exposure_us, "--exposure-us", camera, rep)
    _auto_off(nm, "GainAuto", rep)
    set_enum(nm, "GainSelector", "All")
    _set_float(nm, "Gain", gain_db, "--gain-db", camera, rep)
    _auto_off(nm, "BalanceWhiteAuto", rep)
    _set_balance(nm, balance_ratio, camera, rep)
    if gamma is not None:
        enable = node(nm, "GammaEnable")
        if writable(enable):
            enable.value = True
    _set_float(nm, "Gamma", gamma, "--gamma", camera, rep)
    rep.settings = read_settings(nm)
    return rep


def _auto_off(nm, name: str, rep: FeatureReport) -> None:
    n = node(nm, name)
    if n is None:
        return
    if set_enum(nm, name, "Off"):
        rep.locked.append(name)
    else:
        rep.notes.append(f"{name} could not be turned off (it reads {_value(n)!r})")


def _set_float(nm, name: str, value: float | None, flag: str, camera: str,
               rep: FeatureReport) -> None:
    n = node(nm, name)
    if n is None:
        rep.missing.append(name)
        if value is not None:
            raise ConfigError(f"{camera} has no {name} feature (GenICam SFNC), so {flag} "
                              f"cannot be set; leave it out")
        return
    if value is None:
        return
    if not writable(n):
        raise ConfigError(f"{camera}: {name} is read-only now, so {flag} {value:g} cannot be "
                          f"set")
    lo, hi = float(n.min), float(n.max)
    if not lo <= value <= hi:
        raise ConfigError(f"{flag} {value:g} is outside {camera}'s {name} range {lo:g}..{hi:g}"
                          f"{_unit(n)}")
    n.value = float(value)
    got = float(n.value)
    if abs(got - value) > SET_REL_TOL * max(abs(value), 1e-9):
        rep.notes.append(f"{name} set to {value:g} reads back {got:g}")
        log.warning("%s: %s set to %g reads back %g", camera, name, value, got)


def _set_balance(nm, ratio: tuple[float, float, float] | None, camera: str,
                 rep: FeatureReport) -> None:
    sel, n = node(nm, "BalanceRatioSelector"), node(nm, "BalanceRatio")
    if sel is None or n is None:
        rep.missing.append("BalanceRatio")
        if ratio is not None:
            raise ConfigError(f"{camera} has no BalanceRatio/BalanceRatioSelector features "
                              f"(GenICam SFNC), so --balance-ratio cannot be set; leave it out")
        return
    if ratio is None:
        return
    for channel, value in zip(BALANCE_CHANNELS, ratio, strict=True):
        if not set_enum(nm, "BalanceRatioSelector", channel):
            raise ConfigError(f"{camera}: BalanceRatioSelector has no {channel} entry (it "
                              f"offers {', '.join(symbolics(sel))})")
        _set_float(nm, "BalanceRatio", value, f"--balance-ratio ({channel})", camera, rep)


def read_settings(nm, *, balance: bool = True) -> dict[str, float | list[float]]:
    """Exposure, gain, white balance and gamma as the camera reads them now, under their
    armstereo.camera_settings names (units from the nodes: ``exposure_us`` when ExposureTime
    is in microseconds, ``gain_db`` when Gain is in dB, else the device's own unit).
    ``balance=False`` skips the white balance (reading it switches a selector three times)."""
    out: dict[str, float | list[float]] = {}
    exposure = node(nm, "ExposureTime")
    if readable(exposure):
        unit = _unit_text(exposure)
        out["exposure_us" if unit in ("us", "µs", "\u03bcs") else "exposure"] = \
            float(exposure.value)
    gain = node(nm, "Gain")
    if readable(gain):
        out["gain_db" if _unit_text(gain).lower() == "db" else "gain"] = float(gain.value)
    ratios = _balance_ratios(nm) if balance else None
    if ratios is not None:
        out["balance_ratio"] = ratios
    gamma = node(nm, "Gamma")
    if readable(gamma):
        out["gamma"] = float(gamma.value)
    return {k: v for k, v in out.items()
            if all(math.isfinite(x) for x in (v if isinstance(v, list) else [v]))}


def _balance_ratios(nm) -> list[float] | None:
    sel, n = node(nm, "BalanceRatioSelector"), node(nm, "BalanceRatio")
    if sel is None or not readable(n) or not writable(sel):
        return None
    before = _value(sel)
    values = []
    for channel in BALANCE_CHANNELS:
        if channel not in symbolics(sel):
            return None
        sel.value = channel
        values.append(float(n.value))
    if before in symbolics(sel):
        sel.value = before
    return values


def setup_trigger(nm, mode: str, camera: str) -> str:
    """Trigger mode for ``mode`` (``auto``, ``software``, ``off``): returns ``software`` when
    each frame now waits for :func:`fire`, ``none`` when the camera streams freely. ConfigError
    when ``software`` was asked for and the camera cannot."""
    if mode == "off":
        set_enum(nm, "TriggerMode", "Off")
        return "none"
    missing = [name for name in ("TriggerMode", "TriggerSource", "TriggerSoftware")
               if node(nm, name) is None]
    if not missing and "FrameStart" in symbolics(node(nm, "TriggerSelector")):
        set_enum(nm, "TriggerSelector", "FrameStart")
    ok = not missing and "On" in symbolics(node(nm, "TriggerMode")) \
        and "Software" in symbolics(node(nm, "TriggerSource"))
    if ok:
        set_enum(nm, "TriggerSource", "Software")
        ok = set_enum(nm, "TriggerMode", "On")
    if ok:
        return "software"
    why = (f"it lacks {', '.join(missing)}" if missing
           else "its TriggerMode/TriggerSource offer no software trigger")
    if mode == "software":
        raise ConfigError(f"{camera} cannot be triggered by software ({why}); use "
                          f"--trigger auto or off")
    log.info("%s: no software trigger (%s); acquisition is restarted for every shot so no "
             "frame comes from a buffer", camera, why)
    return "none"


def fire(nm, camera: str) -> None:
    """One software trigger (``TriggerSoftware``); HardwareError if the camera refuses."""
    n = node(nm, "TriggerSoftware")
    if n is None:
        raise HardwareError(f"{camera}: TriggerSoftware is no longer available")
    n.execute()


def enable_frame_chunks(nm) -> list[str]:
    """Turn on the chunks among :data:`FRAME_CHUNKS` the camera offers (per-frame exposure,
    gain and time stamp); returns the ones enabled."""
    active, sel, enable = node(nm, "ChunkModeActive"), node(nm, "ChunkSelector"), \
        node(nm, "ChunkEnable")
    if not writable(active) or sel is None or enable is None:
        return []
    offered = [c for c in FRAME_CHUNKS if c in symbolics(sel)]
    if not offered:
        return []
    active.value = True
    enabled = []
    for chunk in offered:
        sel.value = chunk
        if writable(enable):
            enable.value = True
            enabled.append(chunk)
    return enabled


def frame_chunks(nm, enabled: list[str]) -> tuple[dict[str, float], int | None]:
    """(settings, device time stamp in ns or None) from the chunks of the frame just fetched
    (harvesters updates the chunk nodes when it fetches a buffer)."""
    settings: dict[str, float] = {}
    stamp = None
    for chunk in enabled:
        n = node(nm, f"Chunk{chunk}")
        if not readable(n):
            continue
        value = float(n.value)
        if chunk == "ExposureTime":
            settings["exposure_us" if _unit_text(n) in ("us", "µs", "") else "exposure"] = value
        elif chunk == "Gain":
            settings["gain_db" if _unit_text(n).lower() in ("db", "") else "gain"] = value
        elif value > 0:
            stamp = int(value)  # SFNC ChunkTimestamp: device ticks, ns on most cameras
    return settings, stamp


def _value(n):
    try:
        return n.value
    except Exception:  # noqa: BLE001
        return None


def _unit_text(n) -> str:
    try:
        return str(n.unit).strip()
    except Exception:  # noqa: BLE001
        return ""


def _unit(n) -> str:
    text = _unit_text(n)
    return f" {text}" if text else ""
