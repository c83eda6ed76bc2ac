"""Read camera intrinsics to hold fixed (``armstereo calibrate --intrinsics FILE``).

Accepted: an armstereo mount file (TOML, its ``[camera]`` section); a ROS ``camera_info`` /
OpenCV calibration YAML (``image_width``, ``image_height``, ``camera_matrix: {data: [9]}``,
``distortion_coefficients: {data: [...]}``); or JSON/YAML with ``width``, ``height``, ``K``
(3x3 or 9 numbers) and ``dist``. Pixels; distortion in OpenCV's order (k1, k2, p1, p2[, k3]).
"""

from __future__ import annotations

import json
import tomllib
from pathlib import Path

import numpy as np

from armstereo.camera_model import Intrinsics
from armstereo.errors import ArmstereoError, ConfigError


def read_intrinsics(path: str | Path) -> Intrinsics:
    """Intrinsics from ``path`` (module docstring); one-line ConfigError naming the file."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8-sig")
    except (OSError, UnicodeDecodeError) as err:
        raise ConfigError(f"cannot read the intrinsics file {path}: "
                          f"{getattr(err, 'strerror', None) or 'not a text file'}") from None
    doc = _parse(path, text)
    try:
        return _intrinsics(doc)
    except (KeyError, TypeError, ValueError) as err:
        raise ConfigError(f"intrinsics file {path}: missing or malformed entry ({err}); give "
                          "width, height, K and dist (or a mount file's [camera])") from None
    except ArmstereoError as err:
        raise ConfigError(f"intrinsics file {path}: {err}") from None


def _parse(path: Path, text: str) -> dict:
    suffix = path.suffix.lower()
    try:
        if suffix == ".toml":
            doc = tomllib.loads(text)
        elif suffix == ".json":
            doc = json.loads(text)
        else:
            import yaml

            doc = yaml.safe_load(_strip_opencv_header(text))
    except Exception as err:  # noqa: BLE001 - every parser's own error type: one line
        first = str(err).splitlines()[0] if str(err) else type(err).__name__
        raise ConfigError(f"intrinsics file {path} cannot be parsed: {first}") from None
    if not isinstance(doc, dict):
        raise ConfigError(f"intrinsics file {path}: expected a mapping of named values")
    return doc


def _strip_opencv_header(text: str) -> str:
    """OpenCV's FileStorage YAML starts with ``%YAML:1.0`` and tags matrices ``!!opencv-matrix``,
    which a plain YAML reader refuses; both carry nothing we need."""
    lines = text.splitlines()
    if lines and lines[0].startswith("%YAML:"):
        lines = lines[1:]
    return "\n".join(ln.replace("!!opencv-matrix", "") for ln in lines)


def _intrinsics(doc: dict) -> Intrinsics:
    cam = doc.get("camera", doc)
    if "camera_matrix" in cam:  # ROS camera_info / OpenCV
        K = _numbers(cam["camera_matrix"]["data"] if isinstance(cam["camera_matrix"], dict)
                     else cam["camera_matrix"])
        d = cam.get("distortion_coefficients", {"data": [0.0] * 5})
        dist = _numbers(d["data"] if isinstance(d, dict) else d)
        width = cam.get("image_width", cam.get("width"))
        height = cam.get("image_height", cam.get("height"))
    else:
        K, dist = _numbers(cam["K"]), _numbers(cam.get("dist", [0.0] * 5))
        width, height = cam["width"], cam["height"]
    if K.size != 9:
        raise ValueError(f"K must be 3x3 (9 numbers), got {K.size}")
    if dist.size < 4:
        dist = np.pad(dist, (0, 5 - dist.size))
    return Intrinsics(int(width), int(height), K.reshape(3, 3), dist)


def _numbers(value) -> np.ndarray:
    return np.asarray(value, dtype=float).reshape(-1)
