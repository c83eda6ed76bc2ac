"""armstereo import: a bag recorded like a UR driver and a camera driver do gives pairs at the
true poses and reconstructs; a bag armstereo exported gives its recording back; views that see
a calibration board become a calibration recording that calibrate --from takes."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from armstereo.calibration.board import parse_board
from armstereo.calibration.mount_file import truth_error
from armstereo.calibration.synthetic import simulate_session
from armstereo.reconstruct.pipeline import reconstruct_pair
from armstereo.recording import Recording
from armstereo.ros2.export import export_recording
from armstereo.ros2.importer import ImportOptions, camera_info_topic, import_bag
from armstereo.transforms import invert, rot_z
from tests.armstereo.ros2.conftest import BASELINE, run
from tests.support import SAMPLE_RECORDING
from tests.support.ros2_bags import IMAGE_TOPIC, as_sqlite3_bag, build_driver_bag

POSE_TOLERANCE_M = 1e-5  # 0.01 mm


def _pose_error(T: np.ndarray, truth: np.ndarray) -> tuple[float, float]:
    D = invert(truth) @ T
    angle = math.acos(max(-1.0, min(1.0, (np.trace(D[:3, :3]) - 1) / 2)))
    return float(np.linalg.norm(D[:3, 3])), angle


def _check_views(rec: Recording, driver_bag) -> None:
    assert len(rec.views) == 4 and len(rec.pairs) == 2
    for view, T_true, q_true in zip(rec.views, driver_bag.rest_cameras, driver_bag.rest_joints,
                                    strict=True):
        lin, ang = _pose_error(view.T_base_camera, T_true)
        assert lin < POSE_TOLERANCE_M and ang < 1e-4, (view.index, lin, ang)
        assert np.abs(view.joint_positions - q_true).max() < 2e-5  # encoder noise 2e-6 rad
    for pair in rec.pairs:
        assert abs(pair.achieved_baseline_m - BASELINE) < POSE_TOLERANCE_M
        assert pair.direction == "x"


@pytest.fixture(scope="module")
def imported(driver_bag, tmp_path_factory):
    out = tmp_path_factory.mktemp("imported") / "rec.mcap"
    report = import_bag(driver_bag.path, out, ImportOptions(image_topic=IMAGE_TOPIC,
                                                            baseline=BASELINE))
    return report, Recording.open(out)


def test_driver_bag_gives_pairs_at_the_true_poses(imported, driver_bag):
    report, rec = imported
    assert report["pose_source"] == "tf" and report["camera_frame"] == \
        "camera_color_optical_frame"
    assert not report["from_events"] and not rec.warnings
    _check_views(rec, driver_bag)
    # each view is an image shot at rest (mid-rest), on the camera's own clock
    assert all(v.timestamp_ns % 1_000_000 != 0 for v in rec.views)


def test_the_imported_pair_reconstructs_the_scene(imported, driver_bag, table_scene):
    _, rec = imported
    recon = reconstruct_pair(rec[0])
    left = rec[0].right if recon.swapped else rec[0].left
    truth = table_scene.render(left.T_base_camera, left.intrinsics)[1]
    est = recon.depth_original
    both = np.isfinite(est) & np.isfinite(truth)
    assert both.mean() > 0.5
    err = np.abs(est[both] - truth[both])
    assert np.median(err) < 0.002, np.median(err)  # 2 mm at 0.4-0.55 m, 320x240, 5 cm


def test_sqlite3_bag_folder_gives_the_same_views(driver_bag, tmp_path):
    folder = as_sqlite3_bag(driver_bag.path, tmp_path / "sqlite_bag")
    out = tmp_path / "rec.mcap"
    import_bag(folder, out, ImportOptions(image_topic=IMAGE_TOPIC, baseline=BASELINE))
    _check_views(Recording.open(out), driver_bag)


def test_poses_from_joint_states_with_robot(driver_bag, tmp_path):
    out = tmp_path / "rec.mcap"
    report = import_bag(driver_bag.path, out, ImportOptions(
        image_topic=IMAGE_TOPIC, baseline=BASELINE, tf_topic="/no_tf",
        tf_static_topic="/no_tf_static", robot="ur5e"))
    assert report["pose_source"] == "joints"
    rec = Recording.open(out)
    _check_views(rec, driver_bag)
    assert rec.metadata["robot"] == "ur5e" and rec.metadata["kinematics_source"] == "nominal"


def test_a_baseline_the_bag_does_not_have_pairs_nothing(driver_bag, tmp_path):
    out = tmp_path / "rec.mcap"
    report = import_bag(driver_bag.path, out, ImportOptions(image_topic=IMAGE_TOPIC,
                                                            baseline=0.1))
    assert report["views"] == 4 and report["pairs"] == []
    assert any("50.0 mm apart, not 100.0" in w for w in report["warnings"])


def test_the_import_of_an_export_round_trips(sample_bag, tmp_path):
    out = tmp_path / "back.mcap"
    report = import_bag(sample_bag, out, ImportOptions(image_topic="/camera/image"))
    assert report["from_events"]
    a, b = Recording.open(SAMPLE_RECORDING), Recording.open(out)
    assert not b.warnings
    assert len(a.views) == len(b.views) and len(a.pairs) == len(b.pairs)
    for va, vb in zip(a.views, b.views, strict=True):
        assert (va.index, va.timestamp_ns, va.settle_s) == (vb.index, vb.timestamp_ns,
                                                            vb.settle_s)
        assert np.array_equal(va.image, vb.image)
        assert np.array_equal(va.depth, vb.depth, equal_nan=True)
        assert np.abs(va.T_base_flange - vb.T_base_flange).max() < 1e-12
        assert np.abs(va.T_flange_camera - vb.T_flange_camera).max() < 1e-12
        assert np.array_equal(va.joint_positions, vb.joint_positions)
        assert va.joint_names == vb.joint_names
    for pa, pb in zip(a.pairs, b.pairs, strict=True):
        assert (pa.index, pa.left.index, pa.right.index, pa.commanded_baseline_m,
                pa.achieved_baseline_m, pa.direction, pa.viewpoint) == \
            (pb.index, pb.left.index, pb.right.index, pb.commanded_baseline_m,
             pb.achieved_baseline_m, pb.direction, pb.viewpoint)
    assert a.calibration.size == b.calibration.size
    assert np.array_equal(a.calibration.K, b.calibration.K)
    assert a.start_ns == b.start_ns
    for key, value in a.metadata.items():
        assert b.metadata[key] == value, key
    assert b.metadata["imported_from"] == "ros2"


@pytest.fixture(scope="module")
def calibration_bag(arm, tmp_path_factory):
    """A calibration session with the board on the table: the camera's true mount differs
    from the one its TF (the user's URDF) says; images at 10 Hz, TF at 100 Hz to stay fast."""
    board = parse_board("chessboard:9x6:0.03")
    session = simulate_session(arm, board, n_views=8, arm_error="ideal", render=True, seed=3)

    def render(T, intr, rest):
        return session.images[rest] if rest is not None else np.full(
            (intr.height, intr.width), 128, np.uint8)

    path = tmp_path_factory.mktemp("calib") / "calib.mcap"
    bag = build_driver_bag(path, arm, session.joints, session.true_mount.intrinsics, render,
                           rest_s=0.45, move_s=0.3, tf_hz=100.0, camera_hz=10.0)
    return board, session, bag


def test_board_views_make_a_calibration_recording_calibrate_takes(calibration_bag, tmp_path,
                                                                  capsys):
    board, session, bag = calibration_bag
    out = tmp_path / "session.mcap"
    code, text, err = run(capsys, "import", bag.path, "--image-topic", IMAGE_TOPIC,
                          "--out", out, "--board", board.spec, "--robot", "ur5e")
    assert code == 0 and not err, err
    calib = tmp_path / "session_calibration.mcap"
    assert f"calibrate --from {calib}" in text
    rec = Recording.open(calib)
    assert rec.metadata["purpose"] == "calibration" and len(rec.views) == 8
    code, text, err = run(capsys, "calibrate", "--from", calib, "--out", tmp_path / "m.toml",
                          "--json")
    assert code == 0, err
    from armstereo.mount import CameraMount

    found = CameraMount.load(tmp_path / "m.toml")
    e = truth_error(found, session.true_mount)
    assert e["translation_m"] < 0.0005 and e["rotation_deg"] < 0.05, e
    # the calibration recording exported and imported again is the same session
    export_recording(calib, tmp_path / "calib_bag")
    again = tmp_path / "again.mcap"
    report = import_bag(tmp_path / "calib_bag", again, ImportOptions(image_topic="/camera/image"))
    assert report["from_events"] and report["views"] == 8
    code, _, err = run(capsys, "calibrate", "--from", again, "--out", tmp_path / "m2.toml")
    assert code == 0, err
    same = CameraMount.load(tmp_path / "m2.toml")
    assert np.abs(same.T_flange_camera - found.T_flange_camera).max() < 1e-12
    assert np.abs(same.intrinsics.K - found.intrinsics.K).max() < 1e-9


def test_board_views_without_robot_name_it_and_write_nothing(calibration_bag, tmp_path,
                                                             capsys):
    board, _, bag = calibration_bag
    out = tmp_path / "session.mcap"
    code, _, err = run(capsys, "import", bag.path, "--image-topic", IMAGE_TOPIC, "--out", out,
                       "--board", board.spec)
    assert code == 2 and len(err) == 1 and "give --robot" in err[0], err
    assert not out.exists()


def test_cli_import_prints_pairs(driver_bag, tmp_path, capsys):
    out = tmp_path / "rec.mcap"
    code, text, err = run(capsys, "import", driver_bag.path, "--image-topic", IMAGE_TOPIC,
                          "--out", out, "--baseline", BASELINE, "--json")
    assert code == 0 and not err
    report = json.loads(text)
    assert [p["direction"] for p in report["pairs"]] == ["x", "x"]
    code, _, err = run(capsys, "import", driver_bag.path, "--image-topic", IMAGE_TOPIC,
                       "--out", out)
    assert code == 2 and len(err) == 1 and "--force" in err[0]


@pytest.mark.parametrize("image,info", [("/cam/image_raw", "/cam/camera_info"),
                                        ("/cam/image_raw/compressed", "/cam/camera_info"),
                                        ("image", "/camera_info")])
def test_camera_info_topic_is_image_transports_sibling(image, info):
    assert camera_info_topic(image) == info


def test_direction_names_follow_the_camera_axes():
    from armstereo.ros2.rest import direction_label

    assert direction_label(np.array([0.0, -0.04, 0.0])) == "-y"
    assert direction_label(rot_z(0.3) @ np.array([1.0, 0, 0])) == "0.9553,0.2955,0.0000"


def test_round_trip_of_an_exported_capture_through_the_cli(tmp_path, capsys):
    bag = tmp_path / "bag"
    export_recording(SAMPLE_RECORDING, bag)
    code, text, err = run(capsys, "import", bag, "--image-topic", "/camera/image", "--out",
                          tmp_path / "r.mcap")
    assert code == 0 and "from its capture events" in text
    code, _, err = run(capsys, "inspect", tmp_path / "r.mcap")
    assert code == 0, err
