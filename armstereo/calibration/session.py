"""Calibration recordings: what a calibration session stores beyond a capture's views, and
reading one back for an offline recomputation (``armstereo calibrate --from CALIB.mcap``).

A calibration session is an ordinary armstereo recording (``RecordingWriter.write_view`` per
view: image, actual joints, /tf with the *nominal* mount) whose ``armstereo`` metadata record
also holds the keys below. The computation uses only the images, the joints and the arm model
named in the metadata, so a recomputation gives the same mount.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from armstereo.calibration.board import Board, parse_board
from armstereo.calibration.calibrate import (
    Calibration,
    CalibrationOptions,
    calibrate_from_views,
)
from armstereo.errors import ArmstereoError, RecordingError
from armstereo.kinematics import ArmModel
from armstereo.recording import Recording

PURPOSE_KEY = "purpose"
PURPOSE = "calibration"
BOARD_KEY = "calibration_board"  # the --board spec
VIEWS_KEY = "calibration_views_planned"


def calibration_metadata(board: Board, views_planned: int) -> dict[str, str]:
    """Metadata entries a calibration recording adds to the capture's (``model_metadata``)."""
    return {PURPOSE_KEY: PURPOSE, BOARD_KEY: board.spec, VIEWS_KEY: str(int(views_planned))}


@dataclass
class CalibrationSession:
    """Views of a recorded calibration session: images (uint8), actual joints (rad), the
    board, the robot model name and the mount the session ran with (TOML text)."""

    path: Path
    images: list[np.ndarray]
    joints: list[np.ndarray]
    board: Board
    robot: str
    mount_toml: str
    view_indices: list[int]
    warnings: list[str] = field(default_factory=list)


def read_calibration_session(path: str | Path, board: Board | None = None) -> CalibrationSession:
    """Read a calibration recording (also a cut-short one: every complete view is used).

    ``board`` overrides the recorded spec. Raises RecordingError when the file is not a
    calibration recording, has no complete view, or a view lacks its image or joints.
    """
    rec = Recording.open(path)
    meta = rec.metadata
    if meta.get(PURPOSE_KEY) != PURPOSE and board is None:
        raise RecordingError(f"{rec.path} is not a calibration recording (no "
                             f"{PURPOSE_KEY}={PURPOSE} in its metadata); pass --board to use "
                             "its views anyway")
    if board is None:
        try:
            board = parse_board(meta.get(BOARD_KEY, ""))
        except ArmstereoError as err:
            raise RecordingError(f"{rec.path}: recorded board spec is unusable ({err})") from None
    if not rec.views:
        raise RecordingError(f"{rec.path} has no complete view")
    images, joints, idx = [], [], []
    for v in rec.views:
        if v.joint_positions is None:
            raise RecordingError(f"{rec.path}: view {v.index} has no joint states")
        images.append(v.image)
        joints.append(np.asarray(v.joint_positions, dtype=float))
        idx.append(v.index)
    robot = meta.get("robot", "")
    if not robot:
        raise RecordingError(f"{rec.path}: metadata names no robot model")
    return CalibrationSession(Path(path), images, joints, board, robot,
                              meta.get("mount_toml", ""), idx, list(rec.warnings))


def calibrate_recording(path: str | Path, *, board: Board | None = None,
                        robot: str | Path | None = None,
                        options: CalibrationOptions | None = None) -> Calibration:
    """``armstereo calibrate --from``: redo the calibration of a recorded session.

    The arm model is the recorded one (by name) unless ``robot`` (a model name or URDF path)
    is given; ``board`` overrides the recorded spec. The report gains ``"recording"`` (path,
    views read, reader warnings).
    """
    session = read_calibration_session(path, board)
    model = ArmModel.load(robot or session.robot)
    cal = calibrate_from_views(session.images, session.joints, model, session.board,
                               options=options or CalibrationOptions())
    cal.report["recording"] = {"path": str(session.path), "views": session.view_indices,
                               "warnings": session.warnings}
    return cal
