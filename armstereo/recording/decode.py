"""Decoding stored payloads (images, ground-truth depth) into numpy arrays; every problem
becomes a :class:`RecordingError` naming the view."""

from __future__ import annotations

import struct

import cv2
import numpy as np
from foxglove_schemas_protobuf.RawImage_pb2 import RawImage

from armstereo.camera_model import Intrinsics
from armstereo.errors import RecordingError

MAX_IMAGE_PIXELS = 1 << 26  # 64 Mpx: refuse to decode absurd image headers


def decode_image(data: bytes, fmt: str, intr: Intrinsics | None, what: str) -> np.ndarray:
    """Decode a CompressedImage payload to uint8 BGR (or grey); RecordingError if bad."""
    size = image_size_from_header(data, fmt)
    if size is not None:
        if size[0] * size[1] > MAX_IMAGE_PIXELS:
            raise RecordingError(f"{what}: image header claims {size[0]}x{size[1]} pixels "
                                 f"(limit {MAX_IMAGE_PIXELS})")
        _check_size(size, intr, what)
    try:
        img = cv2.imdecode(np.frombuffer(data, dtype=np.uint8), cv2.IMREAD_UNCHANGED)
    except Exception as err:  # OpenCV raises cv2.error or MemoryError on hostile data
        raise RecordingError(f"{what}: {fmt} image could not be decoded "
                             f"({type(err).__name__})") from None
    if img is None:
        raise RecordingError(f"{what}: {fmt} image could not be decoded ({len(data)} bytes)")
    if img.dtype != np.uint8:
        raise RecordingError(f"{what}: image is {img.dtype}; armstereo expects 8-bit images")
    if img.ndim == 3 and img.shape[2] == 4:
        img = cv2.cvtColor(img, cv2.COLOR_BGRA2BGR)
    _check_size((img.shape[1], img.shape[0]), intr, what)
    return img


def _check_size(size: tuple[int, int], intr: Intrinsics | None, what: str) -> None:
    if intr is not None and tuple(size) != intr.size:
        raise RecordingError(f"{what}: image is {size[0]}x{size[1]} but the calibration says "
                             f"{intr.width}x{intr.height}")


def decode_depth(msg: RawImage, intr: Intrinsics | None, what: str) -> np.ndarray:
    depth = np.frombuffer(msg.data, dtype="<f4").reshape(msg.height, msg.width)
    _check_size((msg.width, msg.height), intr, what + " depth")
    return depth.astype(np.float32)  # a native, writable copy



def image_size_from_header(data: bytes, fmt: str) -> tuple[int, int] | None:
    """(width, height) read from a PNG or JPEG header without decoding, None if unknown."""
    if fmt == "png" and data[:8] == b"\x89PNG\r\n\x1a\n" and data[12:16] == b"IHDR":
        w, h = struct.unpack(">II", data[16:24])
        return (w, h)
    if fmt == "jpeg" and data[:2] == b"\xff\xd8":
        return _jpeg_size(data)
    return None


def _jpeg_size(data: bytes) -> tuple[int, int] | None:
    i = 2
    while i + 9 <= len(data):
        if data[i] != 0xFF:
            return None
        marker = data[i + 1]
        if marker == 0xFF:  # fill byte
            i += 1
            continue
        if 0xC0 <= marker <= 0xCF and marker not in (0xC4, 0xC8, 0xCC):
            h, w = struct.unpack(">HH", data[i + 5:i + 9])
            return (w, h)
        if marker in (0x01, 0xD8) or 0xD0 <= marker <= 0xD7:
            i += 2
            continue
        i += 2 + struct.unpack(">H", data[i + 2:i + 4])[0]
    return None


