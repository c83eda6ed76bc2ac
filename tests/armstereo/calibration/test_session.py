"""Calibration recordings: written like a capture, read back, recomputed to the same mount."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from armstereo.calibration.board import parse_board
from armstereo.calibration.calibrate import CalibrationOptions, calibrate_from_views
from armstereo.calibration.session import (
    calibrate_recording,
    calibration_metadata,
    read_calibration_session,
)
from armstereo.calibration.synthetic import simulate_session
from armstereo.capture.run import model_metadata
from armstereo.devices import Frame
from armstereo.errors import RecordingError
from armstereo.recording import RecordingWriter
from armstereo.robot.arm_model import ArmModel

from .conftest import BOARD_SPEC

BOARD = parse_board(BOARD_SPEC)
OPTIONS = CalibrationOptions(leave_one_out=False)


def _record(path, model, session, *, calibration=True):
    meta = model_metadata(model)
    if calibration:
        meta.update(calibration_metadata(session.board, len(session.joints)))
    with RecordingWriter(path, metadata=meta) as w:
        w.write_calibration(model.mount.intrinsics, 1)
        for k, (img, q) in enumerate(zip(session.images, session.joints, strict=True)):
            w.write_view(k, Frame(img, 1_000_000 * (k + 1)), q, model.joint_names,
                         model.flange_pose(q), model.mount.T_flange_camera, settle_s=0.5)


@pytest.fixture(scope="module")
def rendered(ur5e):
    return simulate_session(ur5e, BOARD, arm_error="ur_like", seed=6, n_views=8, render=True)


def test_recomputing_a_recorded_session_gives_the_same_mount(ur5e, rendered, tmp_path):
    path = tmp_path / "calib.mcap"
    _record(path, ur5e, rendered)
    live = calibrate_from_views(rendered.images, rendered.joints, ur5e, BOARD, options=OPTIONS)
    sess = read_calibration_session(path)
    assert sess.board == BOARD and sess.robot == "ur5e" and sess.view_indices == list(range(8))
    model = ArmModel.load(sess.robot)
    offline = calibrate_from_views(sess.images, sess.joints, model, sess.board, options=OPTIONS)
    np.testing.assert_allclose(offline.mount.T_flange_camera, live.mount.T_flange_camera,
                               atol=1e-9)
    np.testing.assert_allclose(offline.mount.intrinsics.K, live.mount.intrinsics.K, atol=1e-9)


def test_a_capture_recording_is_not_taken_for_a_calibration(ur5e, rendered, tmp_path):
    path = tmp_path / "capture.mcap"
    _record(path, ur5e, rendered, calibration=False)
    with pytest.raises(RecordingError, match="not a calibration recording"):
        read_calibration_session(path)
    assert len(read_calibration_session(path, board=BOARD).images) == 8


def test_calibrate_recording_is_the_offline_entry_point(ur5e, rendered, tmp_path):
    path = tmp_path / "calib.mcap"
    _record(path, ur5e, rendered)
    cal = calibrate_recording(path, options=OPTIONS)
    live = calibrate_from_views(rendered.images, rendered.joints, ur5e, BOARD, options=OPTIONS)
    np.testing.assert_allclose(cal.mount.T_flange_camera, live.mount.T_flange_camera, atol=1e-9)
    assert cal.report["recording"]["views"] == list(range(8))


def _session_with(metadata: dict, robot: str = "ur5e"):
    from armstereo.calibration.session import CalibrationSession

    return CalibrationSession(Path("x.mcap"), [np.zeros((480, 640), np.uint8)], [np.zeros(6)],
                              BOARD, robot, "", [0], metadata=metadata)


def test_recorded_calibrated_kinematics_are_rebuilt_exactly():
    """A session recorded with the controller's table is recomputed with that table, not the
    nominal model its name gives (nominal kinematics bias the hand-eye)."""
    import json

    from armstereo.calibration.session import recorded_arm_model
    from armstereo.robot.source import kinematics_metadata
    from armstereo.robot.synthetic import synthetic_calibration

    table = synthetic_calibration("ur5e", 3)
    meta = kinematics_metadata(ArmModel.from_dh(table), "controller")
    model = recorded_arm_model(_session_with(meta))
    assert model.dh is not None and model.dh.sha256 == table.sha256
    q = np.array([0.1, -1.2, 1.1, -1.4, -1.5, 0.3])
    np.testing.assert_array_equal(model.flange_pose(q), ArmModel.from_dh(table).flange_pose(q))
    # a nominal session stays on the named model; a damaged table is an error, not a fallback
    assert recorded_arm_model(_session_with({"kinematics_source": "nominal"})).dh is None
    damaged = {**meta, "dh_table": json.dumps({**table.as_dict(), "a": [0.0] * 6})}
    with pytest.raises(RecordingError, match="does not match its dh_sha256"):
        recorded_arm_model(_session_with(damaged))
    with pytest.raises(RecordingError, match="dh_table is unusable"):
        recorded_arm_model(_session_with({**meta, "dh_table": "{not json"}))


def test_mock_truth_is_read_from_the_metadata():
    import json

    from armstereo.calibration.session import mock_true_mount

    assert mock_true_mount(_session_with({})) is None
    K = [[610.0, 0.0, 320.0], [0.0, 611.0, 240.0], [0.0, 0.0, 1.0]]
    truth = {"T_flange_camera": np.eye(4).tolist(), "K": K, "dist": [0.1, 0, 0, 0, 0]}
    mount = mock_true_mount(_session_with({"mock_camera_truth": json.dumps(truth)}))
    assert mount.intrinsics.size == (640, 480) and mount.intrinsics.fx == 610.0
    with pytest.raises(RecordingError, match="mock camera truth is unusable"):
        mock_true_mount(_session_with({"mock_camera_truth": "[]"}))
