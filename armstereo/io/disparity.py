"""Disparity files: PFM (float, exact) and 16-bit PNG (scaled).

Conventions:

- **PFM** (``.pfm``): grey ``Pf``, little-endian, rows stored bottom to top as the format
  says. No disparity is written as +inf (the Middlebury 2014 convention); reading turns inf
  and NaN into NaN.
- **PNG** (``.png``) written here: uint16, value = round(d * 256), 0 = no disparity (the KITTI
  convention), so disparities must be below 256 px (use PFM otherwise). Reading a PNG divides
  by ``scale`` (default 256 for 16-bit files, 1 for 8-bit ones; Middlebury ground truth needs
  its own, e.g. 16 for Tsukuba, 8 for Venus, 4 for Teddy and Cones); 0 reads as NaN.

Files are written atomically (temporary file and rename). Colour views for people are in
:func:`armstereo.io.images.colorize_disparity`.
"""

from __future__ import annotations

import re
from pathlib import Path

import cv2
import numpy as np

from armstereo.errors import StereoError
from armstereo.io.files import write_bytes_atomic
from armstereo.io.images import write_png

PNG_SCALE = 256  # 16-bit PNG value per pixel of disparity (KITTI convention)
DISPARITY_SUFFIXES = (".pfm", ".png")  # what write_disparity can write


def write_disparity(path: str | Path, disp: np.ndarray) -> None:
    """Write float disparity (NaN = none) as ``.pfm`` or 16-bit ``.png`` (see module doc)."""
    path = Path(path)
    disp = np.asarray(disp, np.float32)
    if disp.ndim != 2:
        raise StereoError(f"disparity must be a 2-D array, got shape {disp.shape}")
    suffix = path.suffix.lower()
    if suffix == ".pfm":
        write_pfm(path, disp)
    elif suffix == ".png":
        _write_png(path, disp)
    else:
        raise StereoError(f"{path}: unknown disparity format {suffix!r}; use .pfm or .png")


def read_disparity(path: str | Path, scale: float | None = None) -> np.ndarray:
    """Read ``.pfm`` or ``.png`` disparity as float32, NaN = none (see module doc)."""
    path = Path(path)
    if scale is not None and scale <= 0:
        raise StereoError(f"disparity scale must be > 0, got {scale}")
    suffix = path.suffix.lower()
    if suffix == ".pfm":
        disp = read_pfm(path)
        return disp if scale is None else disp / np.float32(scale)
    if suffix in (".png", ".pgm", ".ppm"):
        return _read_png(path, scale)
    raise StereoError(f"{path}: unknown disparity format {suffix!r}; use .pfm or .png")


def write_pfm(path: str | Path, disp: np.ndarray) -> None:
    """Grey little-endian PFM; NaN written as +inf."""
    data = np.where(np.isfinite(disp), disp, np.inf).astype("<f4")
    H, W = data.shape
    header = f"Pf\n{W} {H}\n-1.0\n".encode("ascii")  # negative scale: little-endian
    write_bytes_atomic(path, header + np.ascontiguousarray(data[::-1]).tobytes())


def read_pfm(path: str | Path) -> np.ndarray:
    """Read a grey (``Pf``) or colour (``PF``, first channel kept) PFM; inf/NaN -> NaN."""
    try:
        raw = Path(path).read_bytes()
    except OSError as err:
        raise StereoError(f"cannot read {path}: {err.strerror}") from err
    m = re.match(rb"(P[Ff])\s+(\d+)\s+(\d+)\s+([-+0-9.eE]+)\s", raw)
    if not m:
        raise StereoError(f"{path}: not a PFM file (bad header)")
    channels = 3 if m.group(1) == b"PF" else 1
    W, H = int(m.group(2)), int(m.group(3))
    try:
        scale = float(m.group(4))
    except ValueError:
        raise StereoError(f"{path}: bad PFM scale {m.group(4)!r}") from None
    dtype = "<f4" if scale < 0 else ">f4"
    count = W * H * channels
    body = raw[m.end():]
    if scale == 0 or len(body) < 4 * count:
        raise StereoError(f"{path}: truncated PFM ({len(body)} bytes of data, "
                          f"{4 * count} expected for {W}x{H}x{channels})")
    data = np.frombuffer(body, dtype, count).reshape(H, W, channels)[::-1, :, 0]
    disp = data.astype(np.float32)
    disp[~np.isfinite(disp)] = np.nan
    return disp


def _write_png(path: Path, disp: np.ndarray) -> None:
    finite = np.isfinite(disp)
    if finite.any() and (disp[finite].min() < 0 or disp[finite].max() >= 65535 / PNG_SCALE):
        raise StereoError(f"{path}: disparities {disp[finite].min():.2f}..{disp[finite].max():.2f}"
                          f" do not fit a 16-bit PNG with scale {PNG_SCALE} "
                          f"(0..{65535 / PNG_SCALE:.2f}); write .pfm instead")
    data = np.zeros(disp.shape, np.uint16)
    # a real disparity of 0 must not read back as "none": it is stored as 1/256 px
    data[finite] = np.clip(np.rint(disp[finite] * PNG_SCALE), 1, 65535).astype(np.uint16)
    write_png(path, data)


def _read_png(path: Path, scale: float | None) -> np.ndarray:
    if not path.is_file():
        raise StereoError(f"cannot read {path}: no such file")
    data = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    if data is None:
        raise StereoError(f"{path}: not a readable image")
    if data.ndim == 3:
        # Middlebury 2001 ground truth has three identical channels; a colour photograph is
        # not a disparity map
        if data.shape[2] not in (3, 4) or not (np.array_equal(data[:, :, 0], data[:, :, 1])
                                               and np.array_equal(data[:, :, 0], data[:, :, 2])):
            raise StereoError(f"{path} is a colour image, not a disparity map (its channels "
                              "differ)")
        data = data[:, :, 0]
    if scale is None:
        scale = PNG_SCALE if data.dtype == np.uint16 else 1.0
    disp = data.astype(np.float32) / np.float32(scale)
    disp[data == 0] = np.nan
    return disp
