"""Argument types for the command line: every value is checked where it is parsed.

Each factory returns an ``argparse`` ``type=`` callable. A bad value ends the command with one
line, ``armstereo <command>: error: argument --flag: <what is wrong>``, and exit 2, before any
file is made or anything moves. The numeric rules are :mod:`armstereo.validate`'s.
"""

from __future__ import annotations

import argparse
import os
from collections.abc import Callable
from pathlib import Path

from armstereo import validate
from armstereo.errors import ArmstereoError


def _typed(check: Callable[[str], object], name: str) -> Callable[[str], object]:
    def convert(text: str):
        try:
            return check(text)
        except ArmstereoError as err:
            # argparse names the flag; our checks name "value": say it once
            raise argparse.ArgumentTypeError(str(err).removeprefix("value ")) from None

    convert.__name__ = name  # argparse names the type in some messages
    return convert


def checked(check: Callable[[str], object]) -> Callable[[str], object]:
    """An argparse ``type=`` from a check that raises ArmstereoError for a bad value (the
    ``type`` an options field's flag names, e.g. ``validate.whole``-based)."""
    return _typed(check, check.__name__.strip("_").replace("_", " "))


def positive(unit: str, *, cap: float | None = None) -> Callable[[str], float]:
    """A finite number > 0 (and <= ``cap``)."""
    return _typed(lambda t: validate.positive(t, "value", unit, cap=cap), "positive number")


def non_negative(unit: str, *, cap: float | None = None) -> Callable[[str], float]:
    """A finite number >= 0 (and <= ``cap``)."""
    return _typed(lambda t: validate.non_negative(t, "value", unit, cap=cap),
                  "non-negative number")


def fraction(lo: float = 0.0, hi: float = 1.0) -> Callable[[str], float]:
    """A finite number in [lo, hi]."""
    return _typed(lambda t: validate.in_range(t, "value", lo, hi), "number")


def whole(lo: int, hi: int) -> Callable[[str], int]:
    """A whole number in lo..hi."""
    return _typed(lambda t: validate.whole(t, "value", lo, hi), "whole number")


def positive_list(unit: str, *, cap: float | None = None) -> Callable[[str], list[float]]:
    """Comma-separated finite numbers > 0 (and <= ``cap``), at least one."""
    def check(text: str) -> list[float]:
        items = [s for s in text.split(",") if s.strip()]
        if not items:
            raise argparse.ArgumentTypeError(f"expected numbers separated by commas, got "
                                             f"{text!r}")
        return [validate.positive(s.strip(), "each value", unit, cap=cap) for s in items]

    return _typed(check, "list of numbers")


def host(text: str) -> str:
    """An IP address or host name (no port, URL or path)."""
    return _typed(lambda t: validate.host(t, "value"), "host")(text)


def input_file(text: str) -> Path:
    """An existing, readable regular file (the same rule and exit code for every command)."""
    path = Path(text)
    if not text.strip():
        raise argparse.ArgumentTypeError("empty path")
    if path.is_dir():
        raise argparse.ArgumentTypeError(f"{path} is a directory, not a file")
    if not path.exists():
        raise argparse.ArgumentTypeError(f"no such file: {path}")
    if not path.is_file():
        raise argparse.ArgumentTypeError(f"{path} is not a regular file")
    if not os.access(path, os.R_OK):
        raise argparse.ArgumentTypeError(f"{path} is not readable (permission denied)")
    return path
