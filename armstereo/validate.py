"""One rule per kind of value: every number a user, a file or a caller gives is checked here.

Each check returns the value as a float (or int) and raises ``error`` (ConfigError by default)
with a one-line message naming what was wrong: ``what`` is the flag, the file field or the
argument (``--speed``, ``camera.K``, ``timeout``), ``unit`` is said in the message. NaN and
infinity are never accepted; booleans are not numbers.
"""

from __future__ import annotations

import math
import re

from armstereo.errors import ArmstereoError, ConfigError


def number(value, what: str, *, error: type[ArmstereoError] = ConfigError) -> float:
    """``value`` as a finite float."""
    try:
        if isinstance(value, bool):
            raise TypeError
        v = float(value)
    except (TypeError, ValueError):
        raise error(f"{what} must be a number, got {value!r}") from None
    if not math.isfinite(v):
        raise error(f"{what} must be a finite number, got {value!r}")
    return v


def positive(value, what: str, unit: str, *, cap: float | None = None,
             error: type[ArmstereoError] = ConfigError) -> float:
    """A finite number > 0 and, with ``cap``, <= cap."""
    v = number(value, what, error=error)
    if v <= 0:
        raise error(f"{what} must be > 0 {unit}, got {value!r}")
    if cap is not None and v > cap:
        raise error(f"{what} {v:g} {unit} exceeds the cap of {cap:g} {unit}")
    return v


def non_negative(value, what: str, unit: str, *, cap: float | None = None,
                 error: type[ArmstereoError] = ConfigError) -> float:
    """A finite number >= 0 and, with ``cap``, <= cap."""
    v = number(value, what, error=error)
    if v < 0:
        raise error(f"{what} must be >= 0 {unit}, got {value!r}")
    if cap is not None and v > cap:
        raise error(f"{what} {v:g} {unit} exceeds the limit of {cap:g} {unit}")
    return v


def in_range(value, what: str, lo: float, hi: float, unit: str = "", *,
             error: type[ArmstereoError] = ConfigError) -> float:
    """A finite number in [lo, hi]."""
    v = number(value, what, error=error)
    if not lo <= v <= hi:
        raise error(f"{what} must be in [{lo:g}, {hi:g}]{' ' + unit if unit else ''}, "
                    f"got {value!r}")
    return v


def whole(value, what: str, lo: int, hi: int, *,
          error: type[ArmstereoError] = ConfigError) -> int:
    """An integer in [lo, hi] (a float with a fractional part is refused)."""
    if isinstance(value, bool) or not isinstance(value, int):
        try:
            f = float(value)
        except (TypeError, ValueError):
            raise error(f"{what} must be a whole number, got {value!r}") from None
        if not (math.isfinite(f) and f.is_integer()):
            raise error(f"{what} must be a whole number, got {value!r}")
        value = int(f)
    if not lo <= value <= hi:
        raise error(f"{what} must be in {lo}..{hi}, got {value}")
    return value


_HOST_LABEL = re.compile(r"[A-Za-z0-9]([A-Za-z0-9-]{0,61}[A-Za-z0-9])?")


def host(value, what: str, *, error: type[ArmstereoError] = ConfigError) -> str:
    """A controller address: an IPv4/IPv6 address or a DNS name (no port, no URL, no path)."""
    text = value.strip() if isinstance(value, str) else ""
    if not text:
        raise error(f"{what} must be an IP address or host name, got {value!r}")
    if ":" in text and re.fullmatch(r"[0-9A-Fa-f:.]+", text) and text.count(":") >= 2:
        return text  # IPv6
    labels = text.rstrip(".").split(".")
    if len(text) > 253 or not all(_HOST_LABEL.fullmatch(label) for label in labels):
        raise error(f"{what} {text!r} is not an IP address or host name (give the address "
                    "only: no port, URL or path)")
    return text
