"""The file a calibrated arm model is saved in (``robot-info --save``) and read back from
(``--robot FILE``), so captures and reconstructions can use an arm's own kinematics offline.

Format: one JSON object (UTF-8), floats written with Python's shortest round-trip repr so every
value comes back bit for bit::

    {
      "format": "armstereo-ur-kinematics", "format_version": 1,
      "model": "ur5e",
      "convention": "T_i = Rz(theta_i + q_i) Tz(d_i) Tx(a_i) Rx(alpha_i); ...",
      "dh": {"theta": [6 rad], "a": [6 m], "d": [6 m], "alpha": [6 rad]},
      "sha256": "<DHTable.sha256 of the dh values>",
      "ur_calibration_hash": "calib_<uint64>",
      "calibration_status": 2, "checksums": [6 uint32] or null,
      "source": "controller",
      "controller": {"host": "192.168.1.10", "software_version": "5.12.0.1101534"},
      "saved_at": "2026-01-31T12:00:00Z"
    }

Reading checks ``format``, ``format_version``, the DH values and that ``sha256`` matches them (a
hand-edited table is refused rather than silently used). ``controller`` and ``saved_at`` are
informational.
"""

from __future__ import annotations

import json
import os
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

from armstereo.errors import ConfigError
from armstereo.mount import CameraMount
from armstereo.robot.arm_model import ArmModel
from armstereo.robot.dh import DHTable, ur_calibration_hash

FORMAT = "armstereo-ur-kinematics"
FORMAT_VERSION = 1
SUFFIX = ".json"
CONVENTION = ("T_i = Rz(theta_i + q_i) Tz(d_i) Tx(a_i) Rx(alpha_i); T_base_tool0 = T_1 ... T_6; "
              "base = the controller's base frame; metres and radians")


@dataclass(frozen=True)
class ModelFile:
    """What a model file holds: the table and where it came from."""

    table: DHTable
    controller: dict = field(default_factory=dict)  # host, software_version (strings)
    saved_at: str = ""


def save_model_file(path: str | Path, table: DHTable, *, host: str = "",
                    software_version: str = "") -> Path:
    """Write ``table`` to ``path`` (replaced atomically); returns the path."""
    path = Path(path)
    doc = {
        "format": FORMAT, "format_version": FORMAT_VERSION, "model": table.model,
        "convention": CONVENTION, "dh": table.as_dict(), "sha256": table.sha256,
        "ur_calibration_hash": ur_calibration_hash(table),
        "calibration_status": table.calibration_status,
        "checksums": list(table.checksums) if table.checksums is not None else None,
        "source": table.source,
        "controller": {"host": host, "software_version": software_version},
        "saved_at": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
    }
    text = json.dumps(doc, indent=2) + "\n"
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", dir=path.parent)
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as f:
            f.write(text)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path


def load_model_file(path: str | Path) -> ModelFile:
    """Read a model file; ConfigError naming the file and the problem if it is not one, is of
    another version, or its table does not match its hash."""
    path = Path(path)
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as err:
        raise ConfigError(f"cannot read robot model file {path}: {err}") from None
    if not isinstance(doc, dict) or doc.get("format") != FORMAT:
        raise ConfigError(f"{path} is not an armstereo robot model file (format {FORMAT!r})")
    if doc.get("format_version") != FORMAT_VERSION:
        raise ConfigError(f"{path}: robot model file version {doc.get('format_version')!r} is "
                          f"not supported (expected {FORMAT_VERSION})")
    try:
        dh = doc["dh"]
        table = DHTable(model=str(doc["model"]), theta=dh["theta"], a=dh["a"], d=dh["d"],
                        alpha=dh["alpha"], source=str(doc.get("source", "file")),
                        calibration_status=doc.get("calibration_status"),
                        checksums=doc.get("checksums"))
    except (KeyError, TypeError) as err:
        raise ConfigError(f"{path}: robot model file lacks or garbles {err}") from None
    except ConfigError as err:
        raise ConfigError(f"{path}: {err}") from None
    if doc.get("sha256") != table.sha256:
        raise ConfigError(f"{path}: the DH table does not match its sha256 (edited by hand or "
                          f"damaged); save it again with armstereo robot-info --save")
    controller = doc.get("controller") if isinstance(doc.get("controller"), dict) else {}
    return ModelFile(table, {str(k): str(v) for k, v in controller.items()},
                     str(doc.get("saved_at", "")))


def is_model_file(name_or_path: str | Path) -> bool:
    """True if ``name_or_path`` names a model file (by its suffix), not a model or a URDF."""
    return Path(str(name_or_path)).suffix.lower() == SUFFIX


def load_arm_model(name_or_path: str | Path,
                   mount: CameraMount | str | Path | None = None) -> ArmModel:
    """What ``--robot`` takes: a bundled model name, a URDF path, or a model file saved by
    ``robot-info --save`` (then the model's FK is that arm's calibrated FK)."""
    if is_model_file(name_or_path):
        return ArmModel.from_dh(load_model_file(name_or_path).table, mount=mount)
    return ArmModel.load(name_or_path, mount=mount)
