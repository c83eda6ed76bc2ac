"""Read the arm's pose for each image from a file another tool wrote (CSV, JSON or YAML).

Three kinds of pose, all in the controller's ``base`` frame (docs/calibration.md has an example
of each):

- ``tcp``: a UR TCP pose as ``getActualTCPPose`` gives it, ``x, y, z`` (m) and the rotation
  vector ``rx, ry, rz`` (rad). With a zero TCP offset this is the flange; otherwise pass the
  TCP offset (``--tcp``) and it is taken off.
- ``matrix``: ``T_base_flange`` as 16 numbers row by row (or 12: the first three rows), or as
  a nested 4x4 list in JSON/YAML.
- ``joints``: joint angles (rad), turned into flange poses by the robot model (``--robot``).

CSV: one pose per line, an optional header naming the columns (``image`` / ``name`` / ``file``
for the image, e.g. ``image,x,y,z,rx,ry,rz``; ``q1..q6`` or ``j1..j6`` for joints; ``m00..m33``
for a matrix), ``#`` comments, commas, semicolons, tabs or spaces between fields. JSON/YAML:
a list of entries, or ``{"poses": [...]}``; an entry is a list of numbers (or a 4x4 list) or a
mapping with an optional ``image`` and one of ``tcp`` (6 numbers, or ``{x, y, z, rx, ry, rz}``),
``T_base_flange`` / ``matrix`` (4x4 or 16 numbers) or ``joints`` / ``q``.

Every problem is a one-line ConfigError naming the file and the line: ``poses.csv:7: ...``.
"""

from __future__ import annotations

import csv
import io
import json
import math
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from armstereo.calibration.poses import rotmat
from armstereo.errors import ConfigError
from armstereo.transforms import make_T

KINDS = ("tcp", "matrix", "joints")
MAX_REACH_M = 5.0  # a translation beyond this is no arm pose in metres (millimetres?)
MAX_ROTVEC_RAD = 2 * math.pi + 1e-6  # a rotation vector beyond this is not radians
MAX_JOINT_RAD = 2 * math.pi * 1.05  # UR joints turn +-2 pi; beyond that: degrees?
RIGID_TOLERANCE = 1e-3  # exported matrices carry a few decimals: snapped onto SO(3)
NAME_KEYS = ("image", "name", "file", "filename", "image_name")
TCP_KEYS = ("tcp", "pose", "tcp_pose")
MATRIX_KEYS = ("T_base_flange", "matrix", "T", "transform")
JOINT_KEYS = ("joints", "q", "joint_positions")
_JOINT_COLUMN = re.compile(r"^(q|j|joint|theta|shoulder|elbow|wrist|base)", re.I)


@dataclass(frozen=True)
class PoseRecord:
    """One pose as read: its line in the file, the image name it names (or None), its kind
    and its numbers (6 for tcp, 16 row-major for matrix, one per joint for joints)."""

    line: int
    name: str | None
    kind: str
    values: np.ndarray


@dataclass(frozen=True)
class PoseFile:
    path: Path
    kind: str
    records: list[PoseRecord]

    @property
    def named(self) -> bool:
        return any(r.name is not None for r in self.records)

    def error(self, record: PoseRecord, text: str) -> ConfigError:
        return ConfigError(f"{self.path}:{record.line}: {text}")


def read_poses(path: str | Path, kind: str = "auto", *, joints_expected: bool = False
               ) -> PoseFile:
    """Parse a pose file (module docstring). ``kind`` is ``auto`` or one of KINDS; with
    ``auto`` six numbers are joints when ``joints_expected`` (a robot model was named) and TCP
    poses otherwise, 12 or 16 numbers a matrix."""
    path = Path(path)
    if kind != "auto" and kind not in KINDS:
        raise ConfigError(f"--pose-format must be auto, {', '.join(KINDS)}; not {kind!r}")
    try:
        text = path.read_text(encoding="utf-8-sig")
    except UnicodeDecodeError:
        raise ConfigError(f"{path}:1: not a text file (CSV, JSON or YAML)") from None
    except OSError as err:
        raise ConfigError(f"cannot read the pose file {path}: {err.strerror}") from None
    suffix = path.suffix.lower()
    if suffix == ".json":
        raw = _tree_records(path, _json_tree(path, text))
    elif suffix in (".yaml", ".yml"):
        raw = _tree_records(path, _yaml_tree(path, text))
    else:
        raw = _csv_records(path, text)
    if not raw:
        raise ConfigError(f"{path}:1: no poses in the file")
    records = [_checked(path, line, name, hint, vals, kind, joints_expected)
               for line, name, hint, vals in raw]
    kinds = {r.kind for r in records}
    if len(kinds) > 1:
        raise ConfigError(f"{path}:{records[0].line}: the file mixes pose kinds "
                          f"({', '.join(sorted(kinds))}); one kind per file")
    _no_duplicate_names(path, records)
    return PoseFile(path, kinds.pop(), records)


# ----------------------------------------------------------------------------------- CSV
def _csv_records(path: Path, text: str) -> list[tuple[int, str | None, str | None, list]]:
    lines = [(k + 1, ln) for k, ln in enumerate(text.splitlines())
             if ln.strip() and not ln.lstrip().startswith("#")]
    if not lines:
        return []
    sample = lines[0][1]
    delim = next((d for d in (",", ";", "\t") if d in sample), None)
    rows = []
    for no, ln in lines:
        fields = next(csv.reader(io.StringIO(ln), delimiter=delim)) if delim else ln.split()
        rows.append((no, [f.strip() for f in fields]))
    header, hint, name_col = None, None, None
    # a header names the columns: text after its first field (a data line may start with the
    # image name but has only numbers after it)
    if not all(_is_number(f) for f in rows[0][1][1:]):
        header = [h.lower() for h in rows[0][1]]
        rows = rows[1:]
        name_col = next((k for k, h in enumerate(header) if h in NAME_KEYS), None)
        hint = _header_kind(header, name_col)
    out = []
    for no, fields in rows:
        if header is not None and len(fields) != len(header):
            raise ConfigError(f"{path}:{no}: {len(fields)} fields, the header has "
                              f"{len(header)}")
        name = None
        if name_col is not None:
            name = fields[name_col]
            fields = fields[:name_col] + fields[name_col + 1:]
        elif header is None and fields and not _is_number(fields[0]):
            name, fields = fields[0], fields[1:]
        out.append((no, name, hint, [_number(path, no, f) for f in fields]))
    return out


def _header_kind(header: list[str], name_col: int | None) -> str | None:
    cols = [h for k, h in enumerate(header) if k != name_col]
    if set(cols) >= {"x", "y", "z", "rx", "ry", "rz"}:
        return "tcp"
    if cols and all(_JOINT_COLUMN.match(h) for h in cols):
        return "joints"
    if len(cols) in (12, 16) and all(re.match(r"^[mtr]_?\d\d$", h) for h in cols):
        return "matrix"
    return None


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def _number(path: Path, line: int, text) -> float:
    if isinstance(text, bool):
        raise ConfigError(f"{path}:{line}: {text!r} is not a number")
    try:
        v = float(text)
    except (TypeError, ValueError):
        raise ConfigError(f"{path}:{line}: {text!r} is not a number") from None
    if not math.isfinite(v):
        raise ConfigError(f"{path}:{line}: {text!r} is not a finite number")
    return v


# ----------------------------------------------------------------------------- JSON / YAML
@dataclass
class _Node:
    """A parsed value with the line (1-based) it starts on."""

    line: int
    value: object  # str | list[_Node] | dict[str, _Node]


def _json_tree(path: Path, text: str) -> _Node:
    try:
        json.loads(text)  # JSON's own syntax check, with JSON's line numbers
    except json.JSONDecodeError as err:
        raise ConfigError(f"{path}:{err.lineno}: not valid JSON ({err.msg})") from None
    return _yaml_tree(path, text)  # JSON is YAML: its composer gives every node a line


def _yaml_tree(path: Path, text: str) -> _Node:
    import yaml

    try:
        node = yaml.compose(text, Loader=yaml.SafeLoader)
    except yaml.MarkedYAMLError as err:
        line = err.problem_mark.line + 1 if err.problem_mark else 1
        raise ConfigError(f"{path}:{line}: not valid YAML ({err.problem})") from None
    except yaml.YAMLError as err:
        raise ConfigError(f"{path}:1: not valid YAML ({err})") from None
    if node is None:
        return _Node(1, [])
    return _convert(node)


def _convert(node) -> _Node:
    import yaml

    line = node.start_mark.line + 1
    if isinstance(node, yaml.SequenceNode):
        return _Node(line, [_convert(n) for n in node.value])
    if isinstance(node, yaml.MappingNode):
        return _Node(line, {str(k.value): _convert(v) for k, v in node.value})
    return _Node(line, node.value)


def _tree_records(path: Path, root: _Node) -> list[tuple[int, str | None, str | None, list]]:
    entries = root.value
    if isinstance(entries, dict):
        if "poses" not in entries:
            raise ConfigError(f"{path}:{root.line}: expected a list of poses or a mapping "
                              "with a 'poses' list")
        entries = entries["poses"].value
        root = root.value["poses"]
    if not isinstance(entries, list):
        raise ConfigError(f"{path}:{root.line}: expected a list of poses")
    return [_entry(path, e) for e in entries]


def _entry(path: Path, e: _Node) -> tuple[int, str | None, str | None, list]:
    if isinstance(e.value, list):
        return e.line, None, None, _flat(path, e)
    if not isinstance(e.value, dict):
        raise ConfigError(f"{path}:{e.line}: a pose must be a list of numbers or a mapping, "
                          f"not {e.value!r}")
    d = e.value
    name = next((d[k].value for k in NAME_KEYS if k in d), None)
    if name is not None and not isinstance(name, str):
        raise ConfigError(f"{path}:{e.line}: the image name must be text")
    for keys, kind in ((TCP_KEYS, "tcp"), (MATRIX_KEYS, "matrix"), (JOINT_KEYS, "joints")):
        key = next((k for k in keys if k in d), None)
        if key is None:
            continue
        v = d[key]
        if kind == "tcp" and isinstance(v.value, dict):
            missing = [k for k in ("x", "y", "z", "rx", "ry", "rz") if k not in v.value]
            if missing:
                raise ConfigError(f"{path}:{v.line}: the TCP pose lacks {', '.join(missing)}")
            return e.line, name, kind, [_number(path, v.value[k].line, v.value[k].value)
                                        for k in ("x", "y", "z", "rx", "ry", "rz")]
        return e.line, name, kind, _flat(path, v)
    if set(d) >= {"x", "y", "z", "rx", "ry", "rz"}:
        return e.line, name, "tcp", [_number(path, d[k].line, d[k].value)
                                     for k in ("x", "y", "z", "rx", "ry", "rz")]
    raise ConfigError(f"{path}:{e.line}: the entry has none of "
                      f"{', '.join(TCP_KEYS + MATRIX_KEYS + JOINT_KEYS)}")


def _flat(path: Path, n: _Node) -> list[float]:
    if isinstance(n.value, list):
        if n.value and all(isinstance(c.value, list) for c in n.value):
            return [x for c in n.value for x in _flat(path, c)]
        out = []
        for c in n.value:
            if isinstance(c.value, (list, dict)):
                raise ConfigError(f"{path}:{c.line}: expected a number")
            out.append(_number(path, c.line, c.value))
        return out
    raise ConfigError(f"{path}:{n.line}: expected a list of numbers, not {n.value!r}")


# ------------------------------------------------------------------------------- checks
def _checked(path: Path, line: int, name: str | None, hint: str | None, vals: list,
             kind: str, joints_expected: bool) -> PoseRecord:
    v = np.asarray(vals, dtype=float)
    k = kind if kind != "auto" else hint or _kind_by_count(path, line, v.size, joints_expected)
    if k == "tcp":
        _check_tcp(path, line, v)
    elif k == "matrix":
        v = _check_matrix(path, line, v)
    else:
        _check_joints(path, line, v)
    return PoseRecord(line, name, k, v)


def _kind_by_count(path: Path, line: int, n: int, joints_expected: bool) -> str:
    if n in (12, 16):
        return "matrix"
    if n == 6:
        return "joints" if joints_expected else "tcp"
    raise ConfigError(f"{path}:{line}: {n} numbers; a pose is 6 (x, y, z, rx, ry, rz or six "
                      "joints) or 12/16 (T_base_flange row by row)")


def _check_tcp(path: Path, line: int, v: np.ndarray) -> None:
    if v.size != 6:
        raise ConfigError(f"{path}:{line}: a TCP pose is 6 numbers (x, y, z in m, rx, ry, rz "
                          f"in rad), got {v.size}")
    if np.linalg.norm(v[:3]) > MAX_REACH_M:
        raise ConfigError(f"{path}:{line}: the position is {np.linalg.norm(v[:3]):.0f} m from "
                          "the base; x, y, z must be metres (millimetres?)")
    if np.linalg.norm(v[3:]) > MAX_ROTVEC_RAD:
        raise ConfigError(f"{path}:{line}: rx, ry, rz must be a rotation vector in radians "
                          f"(its length is {np.linalg.norm(v[3:]):.1f}; degrees?)")


def _check_matrix(path: Path, line: int, v: np.ndarray) -> np.ndarray:
    if v.size == 12:
        v = np.concatenate([v, [0.0, 0.0, 0.0, 1.0]])
    if v.size != 16:
        raise ConfigError(f"{path}:{line}: T_base_flange is 16 numbers (or 12: three rows), "
                          f"got {v.size}")
    T = v.reshape(4, 4)
    if not np.allclose(T[3], [0, 0, 0, 1], atol=1e-9):
        raise ConfigError(f"{path}:{line}: the last row of T_base_flange must be 0 0 0 1, "
                          f"got {T[3].tolist()}")
    R = T[:3, :3]
    dev = float(np.abs(R @ R.T - np.eye(3)).max())
    if dev > RIGID_TOLERANCE or np.linalg.det(R) <= 0:
        raise ConfigError(f"{path}:{line}: the rotation part of T_base_flange is no rotation "
                          f"(|R R^T - I| = {dev:.2g}, det {np.linalg.det(R):.3g})")
    if np.linalg.norm(T[:3, 3]) > MAX_REACH_M:
        raise ConfigError(f"{path}:{line}: the translation is {np.linalg.norm(T[:3, 3]):.0f} "
                          "m; T_base_flange must be in metres (millimetres?)")
    U, _, Vt = np.linalg.svd(R)
    T = T.copy()
    T[:3, :3] = U @ Vt
    return T.reshape(16)


def _check_joints(path: Path, line: int, v: np.ndarray) -> None:
    if v.size < 1:
        raise ConfigError(f"{path}:{line}: no joint angles")
    if np.max(np.abs(v)) > MAX_JOINT_RAD:
        raise ConfigError(f"{path}:{line}: a joint angle of {np.max(np.abs(v)):.1f}; joint "
                          "angles must be radians (degrees?)")


def _no_duplicate_names(path: Path, records: list[PoseRecord]) -> None:
    seen: dict[str, int] = {}
    for r in records:
        if r.name is None:
            continue
        if r.name in seen:
            raise ConfigError(f"{path}:{r.line}: image {r.name!r} already has a pose (line "
                              f"{seen[r.name]})")
        seen[r.name] = r.line


# --------------------------------------------------------------------------- conversion
def flange_pose(record: PoseRecord, T_flange_tcp: np.ndarray | None = None) -> np.ndarray:
    """T_base_flange of a tcp or matrix record (joints need the arm model: ``model.flange_pose``).
    ``T_flange_tcp``: the TCP offset a tcp pose includes (None: zero)."""
    if record.kind == "matrix":
        return record.values.reshape(4, 4).copy()
    if record.kind != "tcp":
        raise ValueError("joint records need the arm model")
    T = make_T(rotmat(record.values[3:]), record.values[:3])
    if T_flange_tcp is not None:
        T = T @ np.linalg.inv(T_flange_tcp)
    return T
