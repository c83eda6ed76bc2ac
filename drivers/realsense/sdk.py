"""Importing ``pyrealsense2`` (the optional extra ``pip install 'armstereo[realsense]'``).

The SDK's wheel links ``libusb-1.0`` dynamically and does not ship it. Where the system has no
libusb (a minimal container), the ``libusb-package`` wheel (part of the extra) carries one:
it is loaded first, so the SDK finds it by its soname.
"""

from __future__ import annotations

import ctypes
import importlib
import logging

from armstereo.errors import ConfigError

log = logging.getLogger(__name__)

EXTRA_HINT = "pip install 'armstereo[realsense]'"
_rs = None


def rs():
    """The ``pyrealsense2`` module, or ConfigError (exit 2) saying how to install it."""
    global _rs
    if _rs is not None:
        return _rs
    try:
        _rs = importlib.import_module("pyrealsense2")
    except ImportError as err:
        if "libusb" not in str(err) or not _preload_libusb():
            raise ConfigError(f"the realsense camera needs the optional extra: {EXTRA_HINT} "
                              f"({err})") from None
        try:
            _rs = importlib.import_module("pyrealsense2")
        except ImportError as again:
            raise ConfigError(f"the realsense camera needs the optional extra: {EXTRA_HINT} "
                              f"({again})") from None
    return _rs


def _preload_libusb() -> bool:
    """Load libusb-1.0 from the ``libusb-package`` wheel; False if it is not installed."""
    try:
        libusb_package = importlib.import_module("libusb_package")
        path = libusb_package.get_library_path()
    except ImportError:
        return False
    if path is None:
        return False
    try:
        ctypes.CDLL(str(path), mode=ctypes.RTLD_GLOBAL)
    except OSError as err:
        log.debug("could not load %s: %s", path, err)
        return False
    log.debug("loaded libusb from %s for pyrealsense2", path)
    return True


def error_text(err: BaseException) -> str:
    """The SDK's error message in one line."""
    text = str(err).strip().splitlines()
    return text[0] if text else type(err).__name__
