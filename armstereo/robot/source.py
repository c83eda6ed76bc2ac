"""Which kinematics a capture computes its poses with, and how a recording says so.

A connected arm may carry ``kinematics`` (``drivers.ur.primary.ArmKinematics``): the table its
controller broadcast (a UR arm reads it from its read-only primary port at connect, the mock
arm of the realistic profile broadcasts its own). The rule:

1. The controller's calibrated table was read: use it (a ``--robot FILE`` whose table differs
   is reported and overridden: the controller is what moves the arm).
2. Not read, but ``--robot FILE`` gave a saved calibrated model: use the file, say why.
3. Otherwise the model given (nominal DH / URDF). On a real arm that is a warning: camera poses
   may then be millimetres from where the camera was.

Recording metadata keys (documented in recordings/README.md): ``kinematics_source``
(``controller``, ``file``, ``nominal`` or ``urdf``), ``dh_table`` (JSON ``{"theta", "a", "d",
"alpha"}``, rad and m; absent for a custom URDF), ``dh_sha256``, ``ur_calibration_hash``,
``calibration_status`` ("" when none) and ``kinematics_warnings`` (one per line, "" if none).
"""

from __future__ import annotations

import json
import logging
from dataclasses import dataclass

from armstereo.robot.arm_model import ArmModel

log = logging.getLogger(__name__)

SOURCE_CONTROLLER = "controller"
SOURCE_FILE = "file"
SOURCE_NOMINAL = "nominal"
SOURCE_URDF = "urdf"


@dataclass(frozen=True)
class CaptureKinematics:
    """The model a capture uses, where its kinematics came from, and what to warn about."""

    model: ArmModel
    source: str
    warnings: tuple[str, ...] = ()

    def metadata(self) -> dict[str, str]:
        """The recording metadata describing these kinematics (keys in the module doc)."""
        return {**kinematics_metadata(self.model, self.source),
                "kinematics_warnings": "\n".join(self.warnings)}


def choose_kinematics(given: ArmModel, arm, *, live: bool) -> CaptureKinematics:
    """The kinematics for a capture with ``given`` (what ``--robot`` named) on the connected
    ``arm`` (see the module doc for the rule). ``live``: a real arm (a nominal model is then a
    warning). Warnings are also logged."""
    kin = getattr(arm, "kinematics", None)
    from_file = given.dh is not None and given.urdf_path is None
    if kin is not None and kin.calibrated:
        notes = list(kin.warnings)
        if from_file and given.dh.sha256 != kin.table.sha256:
            notes.append(f"the --robot file's table (sha256 {given.dh.sha256[:12]}) is not this "
                         f"arm's (controller: {kin.table.sha256[:12]}); using the controller's")
        chosen = CaptureKinematics(ArmModel.from_dh(kin.table, mount=given.mount),
                                   SOURCE_CONTROLLER, tuple(notes))
    elif from_file:
        reasons = [w for w in (kin.warnings if kin is not None else ())
                   if "NOMINAL" not in w]
        notes = reasons + ([f"the controller's table was not read: using the saved model "
                            f"(sha256 {given.dh.sha256[:12]})"] if kin is not None else [])
        chosen = CaptureKinematics(given, SOURCE_FILE, tuple(notes))
    else:
        source = SOURCE_NOMINAL if _bundled(given) else SOURCE_URDF
        notes = list(kin.warnings) if kin is not None else []
        if live and not any("NOMINAL" in w for w in notes):
            notes.append(f"using the NOMINAL {given.name} kinematics on a real arm: camera poses "
                         f"may be off by millimetres (read the controller's table through its "
                         f"read-only port 30012, or pass --robot FILE saved by robot-info)")
        chosen = CaptureKinematics(given, source, tuple(notes))
    for note in chosen.warnings:
        log.warning("%s", note)
    return chosen


def kinematics_metadata(model: ArmModel, source: str | None = None) -> dict[str, str]:
    """Metadata keys naming ``model``'s kinematics (see the module doc); ``source`` defaults
    to what the model itself says (``nominal`` for a bundled URDF, the table's source)."""
    from armstereo.robot.dh import nominal_table, ur_calibration_hash

    table = model.dh
    if table is None and _bundled(model):
        table = nominal_table(model.name)
    if source is None:
        source = (SOURCE_URDF if table is None else SOURCE_NOMINAL if model.dh is None
                  else table.source)
    out = {"kinematics_source": source}
    if table is not None:
        out.update(dh_table=json.dumps(table.as_dict()), dh_sha256=table.sha256,
                   ur_calibration_hash=ur_calibration_hash(table),
                   calibration_status="" if table.calibration_status is None
                   else str(table.calibration_status))
    return out


def _bundled(model: ArmModel) -> bool:
    """True for a bundled nominal URDF (its FK is the nominal DH table's)."""
    from armstereo.robot.arm_model import MODELS_DIR

    path = model.urdf_path
    return path is not None and path.resolve() == (MODELS_DIR / f"{model.name}.urdf").resolve()
