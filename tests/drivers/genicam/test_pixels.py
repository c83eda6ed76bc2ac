"""PFNC pixel formats to uint8 grey/BGR: bit depths, the four Bayer layouts, colour orders,
and the errors for a short buffer or a format we do not convert."""

from __future__ import annotations

import numpy as np
import pytest

from armstereo.errors import ConfigError, HardwareError
from drivers.genicam import pixels

W, H = 8, 6


def test_mono_deeper_samples_keep_their_top_eight_bits():
    ramp = np.arange(W * H, dtype=np.uint16).reshape(H, W)
    for fmt, bits in (("Mono10", 10), ("Mono12", 12), ("Mono16", 16)):
        samples = (ramp * ((1 << bits) // (W * H))).astype(np.uint16)
        img = pixels.to_image(samples.reshape(-1), W, H, fmt)
        assert img.dtype == np.uint8 and img.shape == (H, W)
        np.testing.assert_array_equal(img, (samples >> (bits - 8)).astype(np.uint8))
    # the payload as raw bytes (little-endian 16-bit containers) is the same frame
    raw = (ramp * 16).astype("<u2").tobytes()
    np.testing.assert_array_equal(pixels.to_image(np.frombuffer(raw, np.uint8), W, H, "Mono12"),
                                  ((ramp * 16) >> 4).astype(np.uint8))
    mono8 = np.arange(W * H, dtype=np.uint8)
    np.testing.assert_array_equal(pixels.to_image(mono8, W, H, "Mono8"), mono8.reshape(H, W))


def mosaic(bgr: np.ndarray, pattern: str) -> np.ndarray:
    """A sensor's raw Bayer frame of ``bgr`` whose first row starts with ``pattern``."""
    index = {"R": 2, "G": 1, "B": 0}
    out = np.empty(bgr.shape[:2], bgr.dtype)
    first, second = pattern, {"RG": "GB", "GR": "BG", "GB": "RG", "BG": "GR"}[pattern]
    for row, colours in ((0, first), (1, second)):
        for col, c in enumerate(colours):
            out[row::2, col::2] = bgr[row::2, col::2, index[c]]
    return out


@pytest.mark.parametrize("pattern", ["RG", "GR", "GB", "BG"])
@pytest.mark.parametrize("bits", [8, 12])
def test_each_bayer_layout_gives_the_scene_colour(pattern, bits):
    scene = np.zeros((32, 32, 3), np.uint8)
    scene[..., 2] = 200  # a red scene: red high, green and blue low
    scene[..., 1] = 40
    scene[..., 0] = 10
    raw = mosaic(scene, pattern).astype(np.uint16) << (bits - 8) if bits > 8 \
        else mosaic(scene, pattern)
    img = pixels.to_image(raw.reshape(-1), 32, 32, f"Bayer{pattern}{bits}")
    inner = img[4:-4, 4:-4].reshape(-1, 3).astype(int)
    assert np.abs(inner - [10, 40, 200]).max() <= 2, (pattern, inner.mean(0))


@pytest.mark.parametrize("fmt,order,channels", [("RGB8", "rgb", 3), ("BGR8", "bgr", 3),
                                                 ("RGBa8", "rgb", 4), ("BGRa8", "bgr", 4)])
def test_colour_orders_end_as_bgr(fmt, order, channels):
    bgr = np.random.default_rng(1).integers(0, 256, (H, W, 3), dtype=np.uint8)
    src = bgr[..., ::-1] if order == "rgb" else bgr
    if channels == 4:
        src = np.concatenate([src, np.full((H, W, 1), 255, np.uint8)], axis=2)
    np.testing.assert_array_equal(pixels.to_image(src.reshape(-1), W, H, fmt), bgr)


def test_a_short_buffer_and_an_unsupported_format_are_named():
    with pytest.raises(HardwareError, match="needs 96 bytes, the buffer holds 10"):
        pixels.to_image(np.zeros(10, np.uint8), W, H, "Mono16")
    with pytest.raises(ConfigError, match="'YUV422Packed' is not supported"):
        pixels.to_image(np.zeros(W * H * 2, np.uint8), W, H, "YUV422Packed")


def test_the_choice_prefers_colour_and_names_what_the_camera_offers():
    assert pixels.choose(["Mono8", "BayerRG8", "RGB8"], None, "cam") == "RGB8"
    assert pixels.choose(["Mono12Packed", "Mono8"], None, "cam") == "Mono8"
    assert pixels.choose(["Mono8", "Mono12"], "Mono12", "cam") == "Mono12"
    with pytest.raises(ConfigError, match=r"cam does not offer pixel format 'RGB8' \(it offers: "
                                          r"RGBa8, Mono8\)"):
        pixels.choose(["RGBa8", "Mono8"], "RGB8", "cam")
    with pytest.raises(ConfigError, match="offers no pixel format armstereo converts"):
        pixels.choose(["YUV422Packed", "Mono12Packed"], None, "cam")


@pytest.mark.parametrize("fmt,channels", [("Mono8", 1), ("BGR8", 3), ("BayerRG8", 1),
                                          ("RGBa8", 4)])
def test_the_image_never_shares_the_producers_buffer(fmt, channels):
    buffer = np.full(W * H * channels, 7, np.uint8)
    img = pixels.to_image(buffer, W, H, fmt)
    buffer[:] = 0  # the producer fills the buffer with the next frame
    assert img.min() == 7
