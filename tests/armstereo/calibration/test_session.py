"""Calibration recordings: written like a capture, read back, recomputed to the same mount."""

from __future__ import annotations

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
from armstereo.kinematics import ArmModel
from armstereo.recording import RecordingWriter

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
