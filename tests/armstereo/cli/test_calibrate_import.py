"""armstereo calibrate --images GLOB --poses FILE: images and poses recorded elsewhere, the
recording it writes, --from on that recording, and one-line errors."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest

from armstereo.apps.calibrate_import import import_views
from armstereo.calibration.board import parse_board
from armstereo.calibration.mount_file import mount_toml, truth_error
from armstereo.calibration.poses import exp6, rotvec
from armstereo.calibration.synthetic import simulate_session
from armstereo.kinematics import ArmModel
from armstereo.mount import CameraMount

from .test_calibrate_cmd import calibrate

BOARD = "chessboard:17x12:0.016"


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    """Nine rendered views of a simulated UR5e session written as another tool would: PNG
    images, a TCP pose CSV naming them, the same poses as a 4x4 JSON (in order), the joints,
    and the true camera; view 4's pose belongs to another moment."""
    model = ArmModel.load("ur5e", mount="default_wrist_camera")
    s = simulate_session(model, parse_board(BOARD), arm_error="ur_like", seed=7, n_views=9,
                         render=True)
    d = tmp_path_factory.mktemp("elsewhere")
    flanges = list(s.T_base_flange_reported)
    flanges[4] = flanges[4] @ exp6([0.02, -0.01, 0.0, 0.012, 0.02, -0.01])
    (d / "img").mkdir()
    rows = ["image,x,y,z,rx,ry,rz"]
    for k, (img, F) in enumerate(zip(s.images, flanges, strict=True)):
        cv2.imwrite(str(d / "img" / f"shot{k + 1}.png"), img)
        v = [*F[:3, 3], *rotvec(F[:3, :3])]
        rows.append(f"shot{k + 1}.png," + ",".join(repr(float(x)) for x in v))
    rows[1:] = rows[1:][::-1]  # by name, not by order
    (d / "tcp.csv").write_text("\n".join(rows) + "\n")
    (d / "poses.json").write_text(json.dumps([F.tolist() for F in flanges]))
    (d / "joints.csv").write_text("".join(",".join(repr(float(x)) for x in q) + "\n"
                                          for q in s.joints))
    truth = s.true_mount
    (d / "truth.toml").write_text(mount_toml("truth", truth.T_flange_camera, truth.intrinsics))
    return d, truth


def test_tcp_csv_calibrates_names_the_bad_view_and_round_trips(folder, tmp_path):
    d, truth = folder
    out = tmp_path / "cam.toml"
    code, stdout, stderr = calibrate(out, "--images", str(d / "img" / "*.png"), "--poses",
                                     str(d / "tcp.csv"), "--board", BOARD, "--json")
    assert code == 0, stderr
    report = json.loads(stdout)
    assert [b["view"] for b in report["views"]["left_out"]] == [4]
    assert report["imported"]["images"][4] == "shot5.png"
    assert report["kinematics"]["source"] == "poses"
    err = truth_error(CameraMount.load(out), truth)
    assert err["translation_m"] < 0.001 and err["rotation_deg"] < 0.1
    # --from on the recording it wrote is the same computation on the same data
    again = tmp_path / "again.toml"
    code, stdout2, stderr = calibrate(again, "--from", str(out.with_suffix(".mcap")), "--json")
    assert code == 0, stderr
    a, b = CameraMount.load(out), CameraMount.load(again)
    np.testing.assert_array_equal(a.T_flange_camera, b.T_flange_camera)
    np.testing.assert_array_equal(a.intrinsics.K, b.intrinsics.K)
    assert json.loads(stdout2)["views"]["left_out"] == report["views"]["left_out"]


REAL = Path(__file__).resolve().parents[2] / "data" / "franka_handeye" / "session_a"


def test_a_real_session_with_held_intrinsics_round_trips(tmp_path):
    """Twelve real Franka views (tests/data/franka_handeye, a development session) with the
    camera's factory intrinsics held (ROS camera_info YAML): it completes, reads every board,
    says in mm that the arm's poses limit it, and --from on its recording agrees."""
    out = tmp_path / "franka.toml"
    code, stdout, stderr = calibrate(out, "--images", str(REAL / "*.png"), "--poses",
                                     str(REAL / "poses.json"), "--intrinsics",
                                     str(REAL / "camera_info.yaml"), "--board",
                                     "charuco:5x7:0.034:0.028:DICT_6X6_250", "--json")
    assert code == 0, stderr
    report = json.loads(stdout)
    assert report["intrinsics"]["source"] == "given"
    assert report["views"]["board_not_found"] == [] and report["views"]["left_out"] == []
    assert report["quality"]["held_out_prediction"]["rms_mm"] > 1.0
    assert report["quality"]["selection"]["pose_limited"]
    assert any("mm off" in w for w in report["warnings"])
    # the camera sits a few cm from the Franka's end-effector frame
    assert 0.03 < report["camera_distance_from_flange_m"] < 0.1
    again = tmp_path / "again.toml"
    code, stdout2, stderr = calibrate(again, "--from", str(out.with_suffix(".mcap")), "--json")
    assert code == 0, stderr
    assert json.loads(stdout2)["intrinsics"]["source"] == "given"
    np.testing.assert_array_equal(CameraMount.load(out).T_flange_camera,
                                  CameraMount.load(again).T_flange_camera)


def test_joint_angles_need_and_use_the_robot_model(folder):
    d, _ = folder
    model = ArmModel.load("ur5e")
    views = import_views(str(d / "img" / "*.png"), d / "joints.csv", model=model)
    assert views.poses.kind == "joints" and len(views.flanges) == 9
    np.testing.assert_allclose(views.flanges[2], model.flange_pose(views.joints[2]))


@pytest.mark.parametrize(("args", "message"), [
    (["--poses", "{d}/tcp.csv"], "--images and --poses go together"),
    (["--images", "{d}/img/*.png", "--poses", "{d}/tcp.csv"], "--board is required"),
    (["--images", "{d}/img/shot1*.png", "--poses", "{d}/poses.json", "--board", BOARD],
     "1 images but 9 poses"),
    (["--images", "{d}/nothing/*.png", "--poses", "{d}/tcp.csv", "--board", BOARD],
     "matches no image file"),
    (["--images", "{d}/img/*.png", "--poses", "{d}/bad.csv", "--board", BOARD],
     "bad.csv:3: 'oops' is not a number"),
    (["--images", "{d}/img/*.png", "--poses", "{d}/joints.csv", "--pose-format", "joints",
      "--board", BOARD], "name the robot model with --robot"),
    (["--images", "{d}/img/*.png", "--poses", "{d}/tcp.csv", "--board", BOARD, "--dry-run"],
     "--dry-run do(es) not apply"),
])
def test_bad_input_is_one_line_and_exit_2(folder, tmp_path, args, message):
    d, _ = folder
    (d / "bad.csv").write_text("0.1,0.2,0.3,0,0,0\n0.1,0.2,0.3,0,0,0\n0.1,oops,0.3,0,0,0\n")
    code, _, stderr = calibrate(tmp_path / "x.toml", *[a.format(d=d) for a in args])
    assert code == 2
    lines = [ln for ln in stderr.splitlines() if ln.strip()]
    assert len(lines) == 1 and message in lines[0], stderr
    assert not (tmp_path / "x.toml").exists() and not Path(tmp_path / "x.mcap").exists()
