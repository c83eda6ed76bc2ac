"""Bags that cannot give views end with one line naming what is missing and exit 2 (a topic or
argument) or 5 (the bag's content); the missing extra is one line with the install hint."""

from __future__ import annotations

import sys

import pytest

from armstereo.ros2 import types as R
from tests.armstereo.ros2 import tiny as T
from tests.armstereo.ros2.conftest import run
from tests.support import SAMPLE_RECORDING


def _one_line(err: list[str], *words: str) -> None:
    assert len(err) == 1, err
    assert "Traceback" not in err[0] and "internal error" not in err[0], err
    for w in words:
        assert w in err[0], err


def _import(capsys, tmp_path, bag: T.Tiny, *extra) -> tuple[int, list[str]]:
    path = bag.write(tmp_path / "bag.mcap")
    code, _, err = run(capsys, "import", path, "--image-topic", T.IMAGE, "--out",
                       tmp_path / "rec.mcap", *extra)
    return code, err


def test_the_tiny_bag_itself_imports(capsys, tmp_path):
    code, err = _import(capsys, tmp_path, T.tiny())
    assert code == 0 and not err


def test_a_missing_image_topic_names_the_bags_image_topics(capsys, tmp_path):
    path = T.tiny().write(tmp_path / "bag.mcap")
    code, _, err = run(capsys, "import", path, "--image-topic", "/camera/image", "--out",
                       tmp_path / "r.mcap")
    assert code == 2
    _one_line(err, "no topic /camera/image", T.IMAGE)


def test_a_missing_camera_info_is_named(capsys, tmp_path):
    code, err = _import(capsys, tmp_path, T.tiny().drop(T.INFO))
    assert code == 2
    _one_line(err, "no topic /cam/camera_info", "no camera info topic")


def test_an_image_topic_of_another_type_is_refused(capsys, tmp_path):
    bag = T.tiny()
    code, _, err = run(capsys, "import", bag.write(tmp_path / "b.mcap"), "--image-topic",
                       R.TOPIC_TF, "--out", tmp_path / "r.mcap")
    assert code == 5
    _one_line(err, "/tf", "carries tf2_msgs/msg/TFMessage", "sensor_msgs/msg/Image")


def test_an_unknown_message_type_is_refused(capsys, tmp_path):
    bag = T.tiny()
    for r in bag.on(T.IMAGE):
        r.msgtype = "acme_msgs/msg/Frame"
    bag.msgdefs["acme_msgs/msg/Frame"] = R.typestore().generate_msgdef(R.IMAGE,
                                                                       ros_version=2)[0]
    code, err = _import(capsys, tmp_path, bag)
    assert code == 5
    _one_line(err, "carries acme_msgs/msg/Frame")


def test_a_non_standard_definition_of_a_standard_type_is_refused(capsys, tmp_path):
    bag = T.tiny()
    text = R.typestore().generate_msgdef(R.IMAGE, ros_version=2)[0]
    bag.msgdefs[R.IMAGE] = text.replace("uint32 step", "uint64 step", 1)
    for r in bag.on(T.IMAGE):
        r.msg["step"] = T.W
    code, err = _import(capsys, tmp_path, bag)
    assert code == 5
    _one_line(err, "definition of sensor_msgs/msg/Image differs")


def test_a_broken_tf_chain_names_both_trees(capsys, tmp_path):
    code, err = _import(capsys, tmp_path, T.tiny().drop(R.TOPIC_TF_STATIC))
    assert code == 5
    _one_line(err, "no frame cam_optical", "--robot")


def test_a_camera_in_another_tree_names_its_root(capsys, tmp_path):
    bag = T.tiny()
    (static,) = bag.on(R.TOPIC_TF_STATIC)
    static.msg["transforms"] = [T.tf("camera_link", T.CAMERA, (0, 0, 0), T.T0)]
    code, err = _import(capsys, tmp_path, bag)
    assert code == 5
    _one_line(err, "no TF chain from tool0 to cam_optical", "cam_optical's at camera_link")


def test_tf_stamps_going_back_in_time_are_refused(capsys, tmp_path):
    bag = T.tiny()
    tfs = bag.on(R.TOPIC_TF)
    tfs[50].msg, tfs[51].msg = tfs[51].msg, tfs[50].msg
    code, err = _import(capsys, tmp_path, bag)
    assert code == 5
    _one_line(err, "base -> tool0", "go back in time", "out of order")


def test_image_stamps_out_of_order_are_refused(capsys, tmp_path):
    bag = T.tiny()
    imgs = bag.on(T.IMAGE)
    imgs[3].msg["header"], imgs[4].msg["header"] = imgs[4].msg["header"], imgs[3].msg["header"]
    code, err = _import(capsys, tmp_path, bag)
    assert code == 5
    _one_line(err, T.IMAGE, "out of order")


def test_a_frame_with_two_parents_is_refused(capsys, tmp_path):
    bag = T.tiny()
    bag.on(R.TOPIC_TF)[7].msg["transforms"][0]["header"]["frame_id"] = "world"
    code, err = _import(capsys, tmp_path, bag)
    assert code == 5
    _one_line(err, "tool0 has two parents")


def test_images_on_another_clock_than_tf_are_named(capsys, tmp_path):
    bag = T.tiny()
    for r in bag.on(R.TOPIC_TF):
        r.msg["transforms"][0]["header"]["stamp"]["sec"] += 1000
    code, err = _import(capsys, tmp_path, bag)
    assert code == 5
    _one_line(err, "does not cover the images' stamps", "one clock")


def test_a_camera_never_at_rest_is_named(capsys, tmp_path):
    bag = T.tiny()
    for k, r in enumerate(bag.on(R.TOPIC_TF)):
        r.msg["transforms"][0]["transform"]["translation"]["x"] = 0.001 * k
    code, err = _import(capsys, tmp_path, bag)
    assert code == 5
    _one_line(err, "none of the 24 images was taken while the camera was at rest")


def test_images_that_disagree_with_their_camera_info_are_named(capsys, tmp_path):
    bag = T.tiny()
    for r in bag.on(T.INFO):
        r.msg["width"] = 32
    code, err = _import(capsys, tmp_path, bag)
    assert code == 5
    _one_line(err, "16x12 but its camera info says 32x12")


def test_an_unsupported_encoding_is_named(capsys, tmp_path):
    bag = T.tiny()
    for r in bag.on(T.IMAGE):
        r.msg["encoding"] = "bayer_rggb8"
    code, err = _import(capsys, tmp_path, bag)
    assert code == 5
    _one_line(err, "encoding 'bayer_rggb8' is not supported")


@pytest.mark.parametrize("content,suffix,code,words", [
    (b"not a bag at all", ".mcap", 5, ["not a readable ROS 2 bag"]),
    (b"", ".db3", 5, ["not a readable ROS 2 bag"]),
    (b"x", ".bag", 2, ["neither a bag folder"]),
])
def test_files_that_are_not_bags(capsys, tmp_path, content, suffix, code, words):
    path = tmp_path / f"x{suffix}"
    path.write_bytes(content)
    got, _, err = run(capsys, "import", path, "--image-topic", T.IMAGE, "--out",
                      tmp_path / "r.mcap")
    assert got == code
    _one_line(err, *words)


def test_the_output_cannot_be_the_bag(capsys, tmp_path):
    path = T.tiny().write(tmp_path / "bag.mcap")
    code, _, err = run(capsys, "import", path, "--image-topic", T.IMAGE, "--out", path,
                       "--force")
    assert code == 2
    _one_line(err, "differ from each other and from the bag")
    assert path.stat().st_size > 1000


def test_a_folder_without_metadata_is_not_a_bag(capsys, tmp_path):
    code, _, err = run(capsys, "import", tmp_path, "--image-topic", T.IMAGE, "--out",
                       tmp_path / "r.mcap")
    assert code == 2
    _one_line(err, "without metadata.yaml")


def test_a_board_no_view_sees_makes_no_calibration_recording(capsys, tmp_path):
    code, err = _import(capsys, tmp_path, T.tiny(), "--board", "chessboard:9x6:0.03")
    assert code == 0 and not err
    assert not (tmp_path / "rec_calibration.mcap").exists()


def test_export_of_a_file_that_is_not_mcap(capsys, tmp_path):
    bad = tmp_path / "x.mcap"
    bad.write_bytes(b"garbage" * 10)
    code, _, err = run(capsys, "export", bad, "--to", "ros2", "--out", tmp_path / "bag")
    assert code == 5
    _one_line(err, "not an MCAP file")
    assert not (tmp_path / "bag").exists()


@pytest.mark.parametrize("argv", [
    ["export", str(SAMPLE_RECORDING), "--to", "ros2", "--out", "{tmp}/bag"],
    ["import", "{bag}", "--image-topic", T.IMAGE, "--out", "{tmp}/r.mcap"],
])
def test_without_the_extra_one_line_says_how_to_install_it(capsys, tmp_path, monkeypatch,
                                                            argv):
    bag = T.tiny().write(tmp_path / "b.mcap")
    for name in [m for m in sys.modules if m == "rosbags" or m.startswith("rosbags.")]:
        monkeypatch.delitem(sys.modules, name)
    monkeypatch.setitem(sys.modules, "rosbags", None)  # import rosbags -> ImportError
    code, _, err = run(capsys, *[a.format(tmp=tmp_path, bag=bag) for a in argv])
    assert code == 2
    _one_line(err, "pip install 'armstereo[ros2]'", "rosbags is not installed")
    assert not (tmp_path / "bag").exists() and not (tmp_path / "r.mcap").exists()
