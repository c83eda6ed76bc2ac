"""Denavit-Hartenberg tables of UR arms and forward kinematics by composing their 4x4 matrices.

Convention (UR's, standard DH): joint i (1..6) contributes
``A_i(q_i) = Rz(theta_i + q_i) Tz(d_i) Tx(a_i) Rx(alpha_i)`` and
``T_base_flange(q) = A_1 A_2 ... A_6``. DH frame 0 is the controller's ``base`` frame (the frame
of ``getActualTCPPose``), DH frame 6 is ``tool0`` (the flange with a zero TCP, z out of it).
Lengths in metres, angles in radians.

A nominal table is UR's published geometry (``theta = 0``). A calibrated table is what the
controller itself uses and broadcasts (nominal plus its factory correction). Its values need
not look like the nominal ones: ``d`` of the three parallel joints can be hundreds of metres with
opposite signs and ``theta`` whole radians, because nearly parallel axes have a far-away common
normal. Only the resulting FK is millimetres from nominal. Never judge a table by its entries:
compare forward kinematics (:func:`fk_difference`).
"""

from __future__ import annotations

import hashlib
import struct
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike

from armstereo.errors import ConfigError
from robot_models.generate_urdfs import SPECS

N_JOINTS = 6
# calibration_status as the controller's calibration file documents it.
CALIBRATION_STATUS_NAMES = {0: "not initialized", 1: "not linearised", 2: "linearised"}
CALIBRATION_LINEARISED = 2
SOURCE_NOMINAL = "nominal"
SOURCE_CONTROLLER = "controller"

MAX_ABS_LENGTH_M = 1e4  # real calibrated d values reach hundreds of metres; more is corruption
_HASH_TAG = b"armstereo-dh-v1"
_SPECS = {spec.name: spec for spec in SPECS}
NOMINAL_MODELS = tuple(_SPECS)

# Joint sets that represent the whole workspace when two tables are compared: uniform in
# [-pi, pi]^6 with a fixed seed, so every comparison is reproducible.
WORKSPACE_SAMPLES = 1000
_WORKSPACE_SEED = 20240611


@dataclass(frozen=True)
class DHTable:
    """One arm's DH table (6 rows) and where it came from.

    ``theta``/``alpha`` in rad, ``a``/``d`` in m, base to flange. ``model``: the UR model it
    belongs to (a name of ``NOMINAL_MODELS``, or "" if unknown). ``source``: "nominal" or
    "controller". ``calibration_status`` (0 not initialized, 1 not linearised, 2 linearised) and
    ``checksums`` (one uint32 per joint) as the controller reports them; None for a nominal table.
    """

    model: str
    theta: tuple[float, ...]
    a: tuple[float, ...]
    d: tuple[float, ...]
    alpha: tuple[float, ...]
    source: str = SOURCE_NOMINAL
    calibration_status: int | None = None
    checksums: tuple[int, ...] | None = None

    def __post_init__(self) -> None:
        for name in ("theta", "a", "d", "alpha"):
            object.__setattr__(self, name, _six_floats(getattr(self, name), name))
        if max(abs(v) for v in self.a + self.d) > MAX_ABS_LENGTH_M:
            raise ConfigError(f"DH table has a length beyond {MAX_ABS_LENGTH_M:g} m: "
                              f"a={list(self.a)}, d={list(self.d)}")
        if self.checksums is not None:
            sums = tuple(int(c) for c in self.checksums)
            if len(sums) != N_JOINTS or any(not 0 <= c < 2**32 for c in sums):
                raise ConfigError(f"DH checksums must be 6 uint32 values, got {sums}")
            object.__setattr__(self, "checksums", sums)
        if self.calibration_status is not None:
            object.__setattr__(self, "calibration_status", int(self.calibration_status))

    @property
    def is_nominal(self) -> bool:
        return self.source == SOURCE_NOMINAL

    @property
    def sha256(self) -> str:
        """Hex SHA-256 of the exact values (theta, a, d, alpha as big-endian doubles): the same
        on every platform and for every bit of every value. Checksums, status, model and
        source are not part of it: it identifies the kinematics, not the record."""
        values = [v + 0.0 for v in self.theta + self.a + self.d + self.alpha]  # -0.0 -> 0.0
        return hashlib.sha256(_HASH_TAG + struct.pack(">24d", *values)).hexdigest()

    @property
    def status_text(self) -> str:
        """The calibration status in words ("none" for a nominal table)."""
        if self.calibration_status is None:
            return "none"
        return CALIBRATION_STATUS_NAMES.get(self.calibration_status, "unknown")

    def rows(self) -> np.ndarray:
        """(6, 4) array of the rows (theta, a, d, alpha)."""
        return np.array([self.theta, self.a, self.d, self.alpha], dtype=float).T

    def as_dict(self) -> dict[str, list[float]]:
        """``{"theta": [6], "a": [6], "d": [6], "alpha": [6]}`` (rad, m)."""
        return {"theta": list(self.theta), "a": list(self.a), "d": list(self.d),
                "alpha": list(self.alpha)}


def nominal_table(model: str) -> DHTable:
    """UR's published DH table of ``model`` (one of NOMINAL_MODELS, case-insensitive): the same
    numbers the bundled URDFs are generated from. Raises ConfigError for another name."""
    key = str(model).lower()
    if key not in _SPECS:
        raise ConfigError(f"no nominal DH table for robot {model!r}; known: "
                          f"{', '.join(NOMINAL_MODELS)}")
    rows = _SPECS[key].dh_rows()  # (a, d, alpha) per joint
    return DHTable(model=key, theta=(0.0,) * N_JOINTS, a=tuple(r[0] for r in rows),
                   d=tuple(r[1] for r in rows), alpha=tuple(r[2] for r in rows))


def link_transforms(table: DHTable, q: ArrayLike) -> np.ndarray:
    """The six matrices ``A_i(q_i)``: shape (..., 6, 4, 4) for ``q`` of shape (..., 6) rad."""
    q = _as_joints(q)
    th = q + np.asarray(table.theta)
    ct, st = np.cos(th), np.sin(th)
    al = np.broadcast_to(np.asarray(table.alpha), th.shape)
    ca, sa = np.cos(al), np.sin(al)
    a = np.broadcast_to(np.asarray(table.a), th.shape)
    d = np.broadcast_to(np.asarray(table.d), th.shape)
    A = np.zeros(th.shape + (4, 4))
    A[..., 0, 0], A[..., 0, 1], A[..., 0, 2], A[..., 0, 3] = ct, -st * ca, st * sa, a * ct
    A[..., 1, 0], A[..., 1, 1], A[..., 1, 2], A[..., 1, 3] = st, ct * ca, -ct * sa, a * st
    A[..., 2, 1], A[..., 2, 2], A[..., 2, 3] = sa, ca, d
    A[..., 3, 3] = 1.0
    return A


def frames(table: DHTable, q: ArrayLike) -> np.ndarray:
    """DH frames 0..6 in ``base``: shape (..., 7, 4, 4); frame 0 is the identity (``base``),
    frame i is ``A_1 ... A_i``, frame 6 is ``T_base_flange`` (tool0)."""
    A = link_transforms(table, q)
    out = np.empty(A.shape[:-3] + (N_JOINTS + 1, 4, 4))
    out[..., 0, :, :] = np.eye(4)
    for i in range(N_JOINTS):
        out[..., i + 1, :, :] = out[..., i, :, :] @ A[..., i, :, :]
    return out


def fk(table: DHTable, q: ArrayLike) -> np.ndarray:
    """``T_base_flange`` (4x4, m) for ``q`` (6,) rad, or (N, 4, 4) for ``q`` of shape (N, 6)."""
    A = link_transforms(table, q)
    T = A[..., 0, :, :]
    for i in range(1, N_JOINTS):
        T = T @ A[..., i, :, :]
    return T


class FKDifference(NamedTuple):
    """How far apart two flange poses are: position (mm) and rotation angle (degrees)."""

    translation_mm: float
    rotation_deg: float


def pose_difference(T_a: ArrayLike, T_b: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """Per pose: translation distance (m) and rotation angle (rad) between two stacks of 4x4
    poses (same shape (..., 4, 4)); the angle is exact near zero (no arccos)."""
    T_a, T_b = np.asarray(T_a, dtype=float), np.asarray(T_b, dtype=float)
    lin = np.linalg.norm(T_a[..., :3, 3] - T_b[..., :3, 3], axis=-1)
    # |R_a - R_b|_F = 2 sqrt(2) sin(angle / 2) for rotations R_a, R_b.
    chord = np.linalg.norm(T_a[..., :3, :3] - T_b[..., :3, :3], axis=(-2, -1))
    ang = 2.0 * np.arcsin(np.clip(chord / (2.0 * np.sqrt(2.0)), 0.0, 1.0))
    return lin, ang


def fk_difference(table_a: DHTable, table_b: DHTable, q: ArrayLike) -> FKDifference:
    """Largest flange-pose difference between two tables' FK over the joint set(s) ``q``
    ((6,) or (N, 6) rad): position in mm and rotation in degrees."""
    lin, ang = pose_difference(fk(table_a, q), fk(table_b, q))
    return FKDifference(float(np.max(lin)) * 1000.0, float(np.degrees(np.max(ang))))


def workspace_joints(samples: int = WORKSPACE_SAMPLES) -> np.ndarray:
    """(samples, 6) joint sets uniform in [-pi, pi] from a fixed seed (reproducible)."""
    rng = np.random.default_rng(_WORKSPACE_SEED)
    return rng.uniform(-np.pi, np.pi, size=(int(samples), N_JOINTS))


def identify_model(table: DHTable,
                   candidates: tuple[str, ...] = NOMINAL_MODELS) -> tuple[str, FKDifference]:
    """The nominal model whose FK is closest to ``table``'s over the workspace sample, and that
    largest difference. A calibrated arm is a few mm / about a degree from its own model and
    centimetres or more from any other."""
    q = workspace_joints(200)
    scored = [(fk_difference(table, nominal_table(name), q), name) for name in candidates]
    best, name = min(scored, key=lambda s: s[0].translation_mm)
    return name, best


def ur_calibration_hash(table: DHTable) -> str:
    """The ``calib_<uint64>`` hash UR's client library and ROS driver print for a table
    (``kinematics.hash`` in a ROS calibration yaml), to match such a file to an arm.

    Their definition: per joint, theta, d, a, alpha printed with C++ stream defaults (6
    significant digits, like ``%g``) and concatenated; the string hashed with libstdc++'s
    64-bit ``std::hash<std::string>``. So it sees only 6 significant digits, and a C++ build
    on another standard library would print another number; use :attr:`DHTable.sha256` to
    identify kinematics exactly.
    """
    text = "".join(f"{t:g}{d:g}{a:g}{al:g}"
                   for t, d, a, al in zip(table.theta, table.d, table.a, table.alpha,
                                          strict=True))
    return f"calib_{_libstdcxx_hash_bytes(text.encode('ascii'))}"


_MASK64 = (1 << 64) - 1
_MURMUR_MUL = (0xC6A4A793 << 32) + 0x5BD1E995
_LIBSTDCXX_SEED = 0xC70F6907


def _libstdcxx_hash_bytes(data: bytes, seed: int = _LIBSTDCXX_SEED) -> int:
    """libstdc++'s 64-bit ``_Hash_bytes`` (a MurmurHash2 variant): 8-byte little-endian words,
    then the tail bytes, then two shift-mix finalisation rounds."""
    def shift_mix(v: int) -> int:
        return v ^ (v >> 47)

    n_aligned = len(data) & ~7
    h = (seed ^ (len(data) * _MURMUR_MUL)) & _MASK64
    for i in range(0, n_aligned, 8):
        word = int.from_bytes(data[i:i + 8], "little")
        h = ((h ^ ((shift_mix((word * _MURMUR_MUL) & _MASK64) * _MURMUR_MUL) & _MASK64))
             * _MURMUR_MUL) & _MASK64
    if len(data) & 7:
        h = ((h ^ int.from_bytes(data[n_aligned:], "little")) * _MURMUR_MUL) & _MASK64
    h = (shift_mix(h) * _MURMUR_MUL) & _MASK64
    return shift_mix(h)


def _six_floats(values, name: str) -> tuple[float, ...]:
    try:
        out = tuple(float(v) for v in values)
    except (TypeError, ValueError):
        raise ConfigError(f"DH {name} must be 6 numbers, got {values!r}") from None
    if len(out) != N_JOINTS or not all(np.isfinite(out)):
        raise ConfigError(f"DH {name} must be 6 finite numbers, got {list(out)}")
    return out


def _as_joints(q: ArrayLike) -> np.ndarray:
    arr = np.asarray(q, dtype=float)
    if arr.ndim == 0 or arr.shape[-1] != N_JOINTS:
        raise ConfigError(f"joints must have shape (6,) or (N, 6) (rad), got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ConfigError("joints must be finite (rad)")
    return arr
