"""Calibration recordings: what a calibration session stores beyond a capture's views, and
reading one back for an offline recomputation (``armstereo calibrate --from CALIB.mcap``).

A calibration session is an ordinary armstereo recording (``RecordingWriter.write_view`` per
view: image, actual joints, /tf with the *nominal* mount) whose ``armstereo`` metadata record
also holds the keys below. The computation uses only the images, the joints and the arm's
kinematics the session recorded (the controller's calibrated DH table when it was read, see
:mod:`armstereo.robot.source`; nominal kinematics would bias the hand-eye), so a
recomputation gives the same mount. A mock session also records the mock camera's truth
(``mock_camera_truth``), which grades the result (``truth_error``).
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from armstereo.calibration.board import Board, parse_board
from armstereo.calibration.calibrate import (
    Calibration,
    CalibrationOptions,
    calibrate_from_poses,
    calibrate_from_views,
)
from armstereo.calibration.mount_file import truth_error
from armstereo.camera_model import Intrinsics
from armstereo.errors import ArmstereoError, ConfigError, RecordingError
from armstereo.mount import CameraMount
from armstereo.photometric.vignetting import Vignetting
from armstereo.recording import Recording
from armstereo.robot.arm_model import ArmModel

PURPOSE_KEY = "purpose"
PURPOSE = "calibration"
BOARD_KEY = "calibration_board"  # the --board spec
VIEWS_KEY = "calibration_views_planned"
# Sessions imported from images and a pose file (``calibrate --images --poses``):
POSE_SOURCE_KEY = "calibration_pose_source"  # "imported"; absent for live sessions
IMPORT_SOURCE = "imported"
IMPORT_POSE_KIND_KEY = "calibration_pose_kind"  # tcp | matrix | joints
IMPORT_POSES_KEY = "calibration_poses_file"
IMPORT_IMAGES_KEY = "calibration_image_names"  # JSON list, in view order
INTRINSICS_KEY = "calibration_intrinsics"  # "given" (recorded on the calibration topic)


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
    metadata: dict[str, str] = field(default_factory=dict)
    # imported TCP / matrix poses: the recorded flange poses (base frame), used instead of
    # joints and kinematics; None for sessions with joints
    flanges: list[np.ndarray] | None = None
    intrinsics: Intrinsics | None = None  # held fixed: recorded as given


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
    pose_only = (meta.get(POSE_SOURCE_KEY) == IMPORT_SOURCE
                 and meta.get(IMPORT_POSE_KIND_KEY) in ("tcp", "matrix"))
    images, joints, idx = [], [], []
    for v in rec.views:
        if v.joint_positions is None and not pose_only:
            raise RecordingError(f"{rec.path}: view {v.index} has no joint states")
        images.append(v.image)
        joints.append(np.asarray(v.joint_positions if v.joint_positions is not None else [],
                                 dtype=float))
        idx.append(v.index)
    robot = meta.get("robot", "")
    if not robot and not pose_only:
        raise RecordingError(f"{rec.path}: metadata names no robot model")
    intrinsics = None
    if meta.get(INTRINSICS_KEY) == "given":
        intrinsics = rec.views[0].intrinsics
        if intrinsics is None:
            raise RecordingError(f"{rec.path}: the intrinsics were held but are not recorded")
    return CalibrationSession(Path(path), images, joints, board, robot,
                              meta.get("mount_toml", ""), idx, list(rec.warnings), dict(meta),
                              [v.T_base_flange.copy() for v in rec.views] if pose_only
                              else None, intrinsics)


# Kinematics sources whose recorded DH table is the arm's calibrated one (robot.source).
CALIBRATED_SOURCES = ("controller", "file")


def recorded_arm_model(session: CalibrationSession) -> ArmModel:
    """The kinematics the session's poses were computed with: the recorded calibrated DH table
    (``kinematics_source`` controller or file), else the named model. RecordingError when the
    recorded table is unreadable or does not match its recorded hash."""
    from armstereo.robot.dh import SOURCE_CONTROLLER, DHTable

    meta = session.metadata
    text = meta.get("dh_table", "")
    if meta.get("kinematics_source") not in CALIBRATED_SOURCES or not text:
        return ArmModel.load(session.robot)
    try:
        values = json.loads(text)
        table = DHTable(model=session.robot, theta=values["theta"], a=values["a"],
                        d=values["d"], alpha=values["alpha"], source=SOURCE_CONTROLLER)
    except (ValueError, TypeError, KeyError, ArmstereoError) as err:
        raise RecordingError(f"{session.path}: the recorded dh_table is unusable ({err})"
                             ) from None
    expected = meta.get("dh_sha256")
    if expected and expected != table.sha256:
        raise RecordingError(f"{session.path}: the recorded dh_table does not match its "
                             f"dh_sha256 (the metadata is damaged)")
    return ArmModel.from_dh(table)


def mock_true_mount(session: CalibrationSession) -> CameraMount | None:
    """The mock camera's true mount recorded with a mock session (``mock_camera_truth``),
    or None for a real camera's session."""
    text = session.metadata.get("mock_camera_truth", "")
    if not text or not session.images:
        return None
    try:
        truth = json.loads(text)
        h, w = session.images[0].shape[:2]
        intr = Intrinsics(w, h, np.asarray(truth["K"], dtype=float),
                          np.asarray(truth["dist"], dtype=float))
        vig = truth.get("vignetting")
        vig = None if vig is None else Vignetting.from_dict(vig, w, h)
        return CameraMount("mock_truth", np.asarray(truth["T_flange_camera"], dtype=float),
                           intr, vignetting=vig)
    except (ValueError, TypeError, KeyError, ArmstereoError) as err:
        raise RecordingError(f"{session.path}: the recorded mock camera truth is unusable "
                             f"({err})") from None


def calibrate_recording(path: str | Path, *, board: Board | None = None,
                        robot: str | Path | None = None,
                        options: CalibrationOptions | None = None) -> Calibration:
    """``armstereo calibrate --from``: redo the calibration of a recorded session.

    The arm's kinematics are the recorded ones (:func:`recorded_arm_model`) unless ``robot``
    (a model name, URDF path or saved model file) is given; ``board`` overrides the recorded
    spec. The report gains ``"recording"`` (path, views read, reader warnings),
    ``"kinematics"`` (source, DH table hash) and, for a mock session, ``"truth_error"``
    (``{"translation_m", "rotation_deg", "focal_rel"}`` against the mock camera's truth).
    """
    from armstereo.robot.model_file import load_arm_model

    session = read_calibration_session(path, board)
    options = options or CalibrationOptions()
    if session.flanges is not None:  # imported poses: no kinematics involved
        if robot:
            raise ConfigError(f"{session.path} holds flange poses, not joints: --robot does "
                              "not apply")
        model = None
        cal = calibrate_from_poses(session.images, session.flanges, session.board,
                                   intrinsics=session.intrinsics, options=options)
    else:
        model = load_arm_model(robot) if robot else recorded_arm_model(session)
        cal = calibrate_from_views(session.images, session.joints, model, session.board,
                                   intrinsics=session.intrinsics, options=options)
    cal.report["recording"] = {"path": str(session.path), "views": session.view_indices,
                               "warnings": session.warnings}
    if model is None:
        cal.report["kinematics"] = {"source": "poses", "model": "", "dh_sha256": "",
                                    "pose_kind": session.metadata.get(IMPORT_POSE_KIND_KEY)}
    else:
        cal.report["kinematics"] = {
            "source": "given" if robot else session.metadata.get("kinematics_source",
                                                                 "unknown"),
            "model": model.name,
            "dh_sha256": model.dh.sha256 if model.dh is not None else "",
        }
    if session.metadata.get(POSE_SOURCE_KEY) == IMPORT_SOURCE:
        cal.report["imported"] = {
            "poses": session.metadata.get(IMPORT_POSES_KEY, ""),
            "pose_kind": session.metadata.get(IMPORT_POSE_KIND_KEY, ""),
            "images": json.loads(session.metadata.get(IMPORT_IMAGES_KEY, "[]")),
        }
    truth = mock_true_mount(session)
    if truth is not None:
        cal.report["truth_error"] = truth_error(cal.mount, truth)
    return cal
