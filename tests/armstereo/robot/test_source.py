"""Captures compute poses with the arm's own calibrated kinematics, record them, and a recording
shows when its poses are not the arm's."""

from __future__ import annotations

import json

import numpy as np
import pytest

from armstereo import backends
from armstereo.capture import CaptureSettings, plan_capture
from armstereo.capture.run import model_metadata
from armstereo.capture.session import capture_to_file
from armstereo.cli.main import main
from armstereo.mount import CameraMount
from armstereo.recording import Recording
from armstereo.recording.inspect import summarize
from armstereo.robot.arm_model import ArmModel
from armstereo.robot.dh import nominal_table
from armstereo.robot.model_file import save_model_file
from armstereo.robot.source import CaptureKinematics, choose_kinematics
from armstereo.robot.synthetic import synthetic_calibration
from drivers.ur.primary import ArmKinematics

SEED = 2
SETTINGS = CaptureSettings(baseline=0.05, direction=np.array([1.0, 0.0, 0.0]), pairs=1,
                           settle_s=0.5)


@pytest.fixture(scope="module")
def nominal() -> ArmModel:
    return ArmModel.load("ur5e", mount=CameraMount.load(None))


def realistic_arm(model, seed=SEED):
    return backends.build_arm("mock", backends.arm_config("mock", profile="realistic",
                                                          seed=seed), model)


def test_capture_reads_the_arms_table_and_records_it(tmp_path):
    out = tmp_path / "rec.mcap"
    assert main(["capture", "--mock-profile", "realistic", "--seed", str(SEED),
                 "--baseline", "0.05", "--out", str(out)]) == 0
    rec = Recording.open(out)
    truth = synthetic_calibration("ur5e", SEED)
    md = rec.metadata
    assert md["kinematics_source"] == "controller" and md["dh_sha256"] == truth.sha256
    assert json.loads(md["dh_table"]) == truth.as_dict()
    assert md["calibration_status"] == "2" and md["mock_profile"] == "realistic"
    assert md["kinematics_warnings"] == ""
    summary = summarize(rec)
    assert summary["fk_vs_controller_max_mm"] < 1e-6 and summary["warnings"] == []
    # the recorded poses are the calibrated FK of the recorded joints
    model = ArmModel.from_dh(truth)
    for v in rec.views:
        assert np.allclose(v.T_base_flange, model.flange_pose(v.joint_positions), atol=1e-9)
    # the baseline achieved is the commanded one, to the encoder noise
    assert abs(rec[0].achieved_baseline_m - 0.05) < 5e-5


def test_the_camera_lands_where_commanded_only_with_the_calibrated_model(nominal):
    landed = {}
    for use_table in (True, False):
        with realistic_arm(nominal) as arm:
            model = (choose_kinematics(nominal, arm, live=False).model if use_table
                     else nominal)
            plan = plan_capture(model, arm.joint_positions(), SETTINGS)
            start = arm.true_flange_pose()
            step = plan.T_base_flange[1][:3, 3] - plan.T_base_flange[0][:3, 3]
            arm.move_linear(plan.T_base_flange[1], 0.05, 0.25)
            arm.wait_until_steady()
            arm.clock.sleep(0.5)
            # where the flange really went, against where the plan meant it to go
            landed[use_table] = np.linalg.norm(arm.true_flange_pose()[:3, 3]
                                               - (start[:3, 3] + step))
    # left: the encoder noise of the start reading (~10 um) and what the controller's
    # calibration cannot hold (the profile's residual, 50 um per axis, and repeatability)
    assert landed[True] < 1.5e-4
    assert landed[False] > 2 * landed[True]  # planned with nominal FK: the move lands elsewhere
    assert landed[False] > 2e-4


def test_a_nominal_model_on_a_calibrated_arm_is_caught_by_inspect(nominal, tmp_path):
    out = tmp_path / "nominal.mcap"
    camera_config = backends.camera_config("mock", profile="realistic", seed=SEED)
    with realistic_arm(nominal) as arm:
        plan = plan_capture(nominal, arm.joint_positions(), SETTINGS)
        with backends.build_camera("mock", camera_config, nominal, arm) as camera:
            capture_to_file(arm, camera, nominal, plan, out,
                            {**model_metadata(nominal), "arm": "ur"}, progress=None)
    rec = Recording.open(out)
    summary = summarize(rec)
    assert rec.metadata["kinematics_source"] == "nominal"
    assert summary["fk_vs_controller_max_mm"] > 0.1
    assert any("not this arm's" in w for w in summary["warnings"])
    assert any("NOMINAL kinematics" in w for w in summary["warnings"])


def test_a_robot_file_of_another_arm_is_overridden_by_the_controller(tmp_path):
    path = save_model_file(tmp_path / "other.json", synthetic_calibration("ur5e", SEED + 1))
    out = tmp_path / "rec.mcap"
    assert main(["capture", "--mock-profile", "realistic", "--seed", str(SEED),
                 "--robot", str(path), "--out", str(out)]) == 0
    md = Recording.open(out).metadata
    assert md["kinematics_source"] == "controller"
    assert md["dh_sha256"] == synthetic_calibration("ur5e", SEED).sha256
    assert "is not this arm's" in md["kinematics_warnings"]


class _Arm:
    """An arm whose controller's table could not be read."""

    def __init__(self, kinematics):
        self.kinematics = kinematics


def test_fallbacks_when_the_table_is_not_read(nominal, tmp_path, caplog):
    unread = ArmKinematics(nominal_table("ur5e"), None, ("port 30012 blocked",
                                                         "using the NOMINAL ur5e kinematics"))
    chosen = choose_kinematics(nominal, _Arm(unread), live=True)
    assert chosen.source == "nominal" and chosen.model is nominal
    assert "port 30012 blocked" in chosen.warnings and "NOMINAL" in caplog.text
    # a saved calibrated model is used instead, and the recording says so
    saved = ArmModel.from_dh(synthetic_calibration("ur5e", SEED), mount=nominal.mount)
    chosen = choose_kinematics(saved, _Arm(unread), live=True)
    assert chosen.source == "file" and chosen.model is saved
    assert not any("NOMINAL" in w for w in chosen.warnings)
    md = chosen.metadata()
    assert md["kinematics_source"] == "file" and md["dh_sha256"] == saved.dh.sha256
    # an arm without a controller table (the ideal mock) and no live motion: no warning
    quiet = choose_kinematics(nominal, _Arm(None), live=False)
    assert quiet == CaptureKinematics(nominal, "nominal", ())
    assert quiet.metadata()["dh_sha256"] == nominal_table("ur5e").sha256
    # a live arm with nothing read at all still warns
    assert any("NOMINAL" in w for w in choose_kinematics(nominal, _Arm(None),
                                                         live=True).warnings)


def test_poses_not_computed_with_the_recorded_table_are_reported(nominal, tmp_path):
    out = tmp_path / "mixed.mcap"
    other = synthetic_calibration("ur5e", SEED)
    with backends.build_arm("mock", backends.arm_config("mock"), nominal) as arm:
        plan = plan_capture(nominal, arm.joint_positions(), SETTINGS)
        with backends.build_camera("mock", backends.camera_config("mock"), nominal,
                                   arm) as camera:
            capture_to_file(arm, camera, nominal, plan, out,
                            {**model_metadata(nominal),
                             "dh_table": json.dumps(other.as_dict())}, progress=None)
    warnings = Recording.open(out).warnings
    assert any("not computed with the recorded kinematics" in w for w in warnings)
