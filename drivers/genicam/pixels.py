"""GenICam pixel formats (PFNC names) to the images armstereo uses: uint8 grey or BGR.

Supported: ``Mono8``, ``Mono10``, ``Mono12``, ``Mono16`` (unpacked, little-endian 16-bit
containers), the four Bayer layouts at 8, 10 and 12 bits (unpacked), ``RGB8``, ``BGR8``,
``RGBa8``, ``BGRa8``. Deeper samples are scaled to 8 bits by dropping their low bits (the
matcher works on 8-bit intensities); Bayer mosaics are demosaiced by OpenCV's edge-aware
interpolation. Packed formats (``Mono12Packed``, ``Mono10p``, ...), YUV and planar layouts are
not: the camera is asked for an unpacked one instead (:data:`PREFERENCE`).
"""

from __future__ import annotations

import cv2
import numpy as np

from armstereo.errors import ConfigError, HardwareError

# Bits per sample of the unpacked formats; grey unless named in COLOR / BAYER.
_MONO = {"Mono8": 8, "Mono10": 10, "Mono12": 12, "Mono16": 16}
# PFNC names the first row's first two pixels (BayerRG: R G / G B). OpenCV names the pattern
# by the second row's second and third pixels, so PFNC RG is OpenCV's BG, and so on.
_BAYER_CODES = {"RG": cv2.COLOR_BayerBG2BGR_EA, "GR": cv2.COLOR_BayerGB2BGR_EA,
                "GB": cv2.COLOR_BayerGR2BGR_EA, "BG": cv2.COLOR_BayerRG2BGR_EA}
_BAYER = {f"Bayer{p}{b}": (p, b) for p in _BAYER_CODES for b in (8, 10, 12)}
_COLOR = {"RGB8": (3, True), "BGR8": (3, False), "RGBa8": (4, True), "BGRa8": (4, False)}
SUPPORTED = tuple(_MONO) + tuple(_BAYER) + tuple(_COLOR)
# What to ask a camera for when the user names no pixel format: colour straight from the
# camera first, then a mosaic we demosaic, then grey; 8 bits first (less to move and convert).
PREFERENCE = ("BGR8", "RGB8", "BayerRG8", "BayerGR8", "BayerGB8", "BayerBG8", "BGRa8", "RGBa8",
              "Mono8", "BayerRG12", "BayerGR12", "BayerGB12", "BayerBG12", "BayerRG10",
              "BayerGR10", "BayerGB10", "BayerBG10", "Mono12", "Mono10", "Mono16")


def is_supported(pixel_format: str) -> bool:
    return pixel_format in SUPPORTED


def choose(available: tuple[str, ...] | list[str], wanted: str | None, camera: str) -> str:
    """The pixel format to set: ``wanted`` if the camera offers it and we convert it, else the
    first of :data:`PREFERENCE` the camera offers. ConfigError naming what it offers."""
    offered = [f for f in available]
    if wanted is not None:
        if wanted not in SUPPORTED:
            raise ConfigError(f"pixel format {wanted!r} is not supported (supported: "
                              f"{', '.join(SUPPORTED)})")
        if wanted not in offered:
            raise ConfigError(f"{camera} does not offer pixel format {wanted!r} (it offers: "
                              f"{', '.join(offered)})")
        return wanted
    for fmt in PREFERENCE:
        if fmt in offered:
            return fmt
    raise ConfigError(f"{camera} offers no pixel format armstereo converts (it offers: "
                      f"{', '.join(offered)}; supported: {', '.join(SUPPORTED)})")


def to_image(data: np.ndarray, width: int, height: int, pixel_format: str) -> np.ndarray:
    """The buffer ``data`` (the payload as delivered, any integer dtype) of a ``width`` x
    ``height`` frame in ``pixel_format`` as uint8: (H, W) grey or (H, W, 3) BGR, never sharing
    the buffer's memory. Raises
    HardwareError when the payload does not hold such a frame, ConfigError for a format that
    is not supported."""
    if pixel_format in _MONO:
        return _to_8bit(_samples(data, width, height, 1, _MONO[pixel_format]),
                        _MONO[pixel_format])
    if pixel_format in _BAYER:
        pattern, bits = _BAYER[pixel_format]
        mosaic = _to_8bit(_samples(data, width, height, 1, bits), bits)
        return cv2.cvtColor(mosaic, _BAYER_CODES[pattern])
    if pixel_format in _COLOR:
        channels, rgb = _COLOR[pixel_format]
        img = _samples(data, width, height, channels, 8)
        code = (cv2.COLOR_RGB2BGR if channels == 3 else cv2.COLOR_RGBA2BGR) if rgb \
            else (None if channels == 3 else cv2.COLOR_BGRA2BGR)
        return np.array(img, copy=True) if code is None else cv2.cvtColor(img, code)
    raise ConfigError(f"pixel format {pixel_format!r} is not supported (supported: "
                      f"{', '.join(SUPPORTED)})")


def _samples(data: np.ndarray, width: int, height: int, channels: int,
             bits: int) -> np.ndarray:
    """The payload as (H, W[, C]) samples: uint8 for 8 bits, little-endian uint16 else."""
    raw = np.asarray(data)
    flat = raw.reshape(-1).view(np.uint8) if raw.dtype != np.uint8 else raw.reshape(-1)
    dtype = np.uint8 if bits == 8 else np.dtype("<u2")
    n = width * height * channels * dtype.itemsize if dtype != np.uint8 else \
        width * height * channels
    if flat.size < n:
        raise HardwareError(f"a {width}x{height} frame needs {n} bytes, the buffer holds "
                            f"{flat.size}")
    values = flat[:n].view(dtype)
    shape = (height, width) if channels == 1 else (height, width, channels)
    return values.reshape(shape)


def _to_8bit(img: np.ndarray, bits: int) -> np.ndarray:
    """8-bit samples in memory of their own: the producer reuses its buffer once it is queued
    again, so nothing returned may be a view of it."""
    if bits == 8:
        return np.array(img, copy=True)
    return (img >> (bits - 8)).astype(np.uint8)
