"""Camera mounts: where the camera sits on the flange (hand-eye) and its intrinsics.

A mount file is TOML::

    name = "default_wrist_camera"
    [hand_eye]                       # T_flange_camera: camera_optical frame in tool0
    translation = [0.0, -0.07, 0.04] # metres
    rotation_rpy = [0.0, 0.0, 0.0]   # radians, R = Rz(yaw) Ry(pitch) Rx(roll)
    [camera]
    width = 640
    height = 480
    K = [[600.0, 0.0, 319.5], [0.0, 600.0, 239.5], [0.0, 0.0, 1.0]]
    dist = [0.0, 0.0, 0.0, 0.0, 0.0]

``rotation_matrix = [[...], [...], [...]]`` may replace ``rotation_rpy``. An optional
``[vignetting]`` section holds the lens's brightness fall-off (``center``, ``k``; see
:mod:`armstereo.photometric.vignetting`), which ``armstereo calibrate`` estimates; files
without it (all older ones) load with ``vignetting = None``.
"""

from __future__ import annotations

import hashlib
import tomllib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from armstereo.camera_model import Intrinsics
from armstereo.errors import ArmstereoError, ConfigError
from armstereo.photometric.vignetting import Vignetting
from armstereo.transforms import as_rigid, make_T, rot_x, rot_y, rot_z
from robot_models import MOUNTS_DIR

DEFAULT_MOUNT = "default_wrist_camera"


@dataclass(frozen=True)
class CameraMount:
    """A camera on the flange: ``T_flange_camera`` (tool0 -> camera_optical) and intrinsics."""

    name: str
    T_flange_camera: np.ndarray
    intrinsics: Intrinsics
    source: str = ""  # the file's text, stored in recordings
    vignetting: Vignetting | None = None  # the lens's fall-off, if the file has the section

    @classmethod
    def load(cls, name_or_path: str | Path | None = None) -> CameraMount:
        """Load a mount by file path or by the name of a file in ``robot_models/mounts/``."""
        path = resolve_mount_path(name_or_path)
        try:
            text = path.read_text(encoding="utf-8")
        except UnicodeDecodeError:
            raise ConfigError(f"mount file {path} is not a text (TOML) file") from None
        except OSError as err:
            raise ConfigError(f"cannot read mount file {path}: {err.strerror}") from None
        try:
            doc = tomllib.loads(text)
        except tomllib.TOMLDecodeError as err:
            raise ConfigError(f"mount file {path} is not valid TOML: {err}") from None
        try:
            return cls.from_dict(doc, source=text)
        except ArmstereoError as err:
            raise ConfigError(f"mount file {path}: {err}") from None
        except (KeyError, TypeError, ValueError) as err:
            raise ConfigError(f"mount file {path}: missing or malformed entry ({err})") from None

    @classmethod
    def from_dict(cls, doc: dict, source: str = "") -> CameraMount:
        """Build a mount from the parsed TOML structure documented in this module."""
        he = doc["hand_eye"]
        t = _finite_array(he["translation"], "hand_eye.translation", (3,))
        if "rotation_matrix" in he:
            R = _finite_array(he["rotation_matrix"], "hand_eye.rotation_matrix", (3, 3))
            what = "hand_eye.rotation_matrix"
        else:
            rpy = _finite_array(he.get("rotation_rpy", [0.0, 0.0, 0.0]),
                                "hand_eye.rotation_rpy", (3,))
            R = rot_z(rpy[2]) @ rot_y(rpy[1]) @ rot_x(rpy[0])
            what = "hand_eye.rotation_rpy"
        # Hand-eye tools print rotations to a few decimals: snap those onto SO(3).
        T = as_rigid(make_T(R, t), what, snap=True)
        cam = doc["camera"]
        intr = Intrinsics(
            width=_whole(cam["width"], "camera.width"),
            height=_whole(cam["height"], "camera.height"),
            K=_finite_array(cam["K"], "camera.K", (3, 3)),
            dist=_finite_array(cam.get("dist", [0.0] * 5), "camera.dist", None),
        )
        vig = doc.get("vignetting")
        if vig is not None:
            try:
                vig = Vignetting.from_dict(vig, intr.width, intr.height)
            except ArmstereoError as err:
                raise ConfigError(f"[vignetting]: {err}") from None
        return cls(name=str(doc.get("name", "mount")), T_flange_camera=T, intrinsics=intr,
                   source=source, vignetting=vig)

    @property
    def sha256(self) -> str:
        return hashlib.sha256(self.source.encode()).hexdigest()


def _finite_array(value, field: str, shape: tuple[int, ...] | None) -> np.ndarray:
    """``value`` as a finite float array of ``shape`` (any 1-D length if None)."""
    try:
        a = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ConfigError(f"{field} must be numbers, got {value!r}") from None
    if (shape is not None and a.shape != shape) or (shape is None and a.ndim != 1):
        want = "x".join(map(str, shape)) if shape else "a list of"
        raise ConfigError(f"{field} must be {want} numbers, got shape {a.shape}")
    if not np.all(np.isfinite(a)):
        raise ConfigError(f"{field} must be finite, got {a.tolist()}")
    return a


def _whole(value, field: str) -> int:
    if isinstance(value, bool) or not isinstance(value, int):
        raise ConfigError(f"{field} must be a whole number of pixels, got {value!r}")
    return value


def resolve_mount_path(name_or_path: str | Path | None) -> Path:
    """Path of a mount file given a path, a bundled mount's name, or None (the default)."""
    if name_or_path is None:
        name_or_path = DEFAULT_MOUNT
    p = Path(name_or_path)
    if p.is_file():
        return p
    bundled = MOUNTS_DIR / f"{p.name.removesuffix('.toml')}.toml"
    if bundled.is_file():
        return bundled
    known = ", ".join(sorted(f.stem for f in MOUNTS_DIR.glob("*.toml")))
    raise ConfigError(f"no mount file {name_or_path!s} (bundled mounts: {known})")
