"""armstereo export --to ros2: every kind of recording, written with rosbags and read back with
the independent reader (mcap + mcap-ros2-support, tests/armstereo/ros2/readback.py)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from armstereo.fusion.foxglove import ViewPose, write_fusion_mcap
from armstereo.fusion.mesh import Mesh
from armstereo.io.ply import read_ply
from armstereo.reconstruct.outputs import write_outputs
from armstereo.reconstruct.pipeline import reconstruct_pair
from armstereo.recording import Recording, RecordingWriter
from armstereo.ros2 import types as R
from armstereo.ros2.export import ExportOptions, export_recording
from armstereo.scene import analyze_scene
from armstereo.scene.foxglove import write_scene_mcap
from armstereo.scene.synthetic import default_truth, scan
from tests.armstereo.ros2.conftest import run
from tests.armstereo.ros2.readback import (
    load_yaml,
    lookup_at,
    read_bag,
    schema_types,
    stamp_ns,
    store_types,
)
from tests.support import SAMPLE_RECORDING
from tests.support.recordings import JOINTS, small_intrinsics, synthetic_views


def _image(msg) -> np.ndarray:
    ch = {"bgr8": 3, "mono8": 1}[msg.encoding]
    a = np.frombuffer(bytes(msg.data), np.uint8).reshape(msg.height, msg.width * ch)
    return a.reshape(msg.height, msg.width, ch) if ch == 3 else a


def _cloud(msg) -> tuple[np.ndarray, np.ndarray]:
    fields = {f.name: (f.offset, f.datatype) for f in msg.fields}
    assert fields == {"x": (0, 7), "y": (4, 7), "z": (8, 7), "rgb": (12, 7)}
    assert msg.point_step == 16 and msg.height == 1 and msg.row_step == 16 * msg.width
    raw = np.frombuffer(bytes(msg.data), np.uint8).reshape(msg.width, 16)
    xyz = raw[:, :12].copy().view("<f4").reshape(-1, 3)
    return xyz, raw[:, 12:15]  # b, g, r of the packed 0x00RRGGBB


def test_capture_reads_back_with_every_message_and_its_stamps(sample_bag):
    rec = Recording.open(SAMPLE_RECORDING)
    bag = read_bag(sample_bag)
    assert bag.profile == "ros2"
    assert {enc for enc, _ in bag.schemas.values()} == {"ros2msg"}
    assert {enc for _, enc, _ in bag.channels.values()} == {"cdr"}
    counts = {t: len(m) for t, m in bag.messages.items()}
    assert counts == {"/tf_static": 1, "/camera/camera_info": 3, "/camera/image": 2,
                      "/camera/depth_truth": 2, "/tf": 2, "/joint_states": 2,
                      "/capture/events": 3}
    images = bag.decoded("/camera/image")
    for view, img in zip(rec.views, images, strict=True):
        assert stamp_ns(img.header.stamp) == view.timestamp_ns
        assert img.header.frame_id == "camera_optical" and img.encoding == "bgr8"
        assert np.array_equal(_image(img), view.image)
        T = lookup_at(bag, "base", "camera_optical", view.timestamp_ns)
        assert T is not None, "TF incomplete at an image stamp"
        assert np.abs(T - view.T_base_camera).max() < 1e-12
    for view, js in zip(rec.views, bag.decoded("/joint_states"), strict=True):
        assert list(js.name) == list(JOINTS) and np.array_equal(js.position,
                                                                 view.joint_positions)
    log_times = [t for t, _ in bag.messages["/camera/image"]]
    assert log_times == [v.timestamp_ns for v in rec.views]
    depth = bag.decoded("/camera/depth_truth")[0]
    assert depth.encoding == "32FC1" and depth.step == 4 * depth.width
    got = np.frombuffer(bytes(depth.data), "<f4").reshape(depth.height, depth.width)
    assert np.array_equal(got, rec.views[0].depth, equal_nan=True)
    events = [json.loads(m.data) for m in bag.decoded("/capture/events")]
    assert [e["event"] for e in events] == ["view", "view", "pair"]


def test_camera_info_and_static_mount(sample_bag):
    rec = Recording.open(SAMPLE_RECORDING)
    bag = read_bag(sample_bag)
    infos = bag.decoded("/camera/camera_info")
    stamps = [stamp_ns(i.header.stamp) for i in infos]
    assert stamps[1:] == [v.timestamp_ns for v in rec.views]  # and one at the calibration
    info = infos[-1]
    assert info.distortion_model == "plumb_bob" and list(info.d) == [0.0] * 5
    assert np.array_equal(np.reshape(info.k, (3, 3)), rec.calibration.K)
    assert np.array_equal(np.reshape(info.p, (3, 4))[:, :3], rec.calibration.K)
    assert (info.width, info.height) == rec.calibration.size
    (static,) = bag.decoded("/tf_static")
    (mount,) = static.transforms
    assert (mount.header.frame_id, mount.child_frame_id) == ("tool0", "camera_optical")
    qos = load_yaml_string(bag.channels["/tf_static"][2]["offered_qos_profiles"])
    assert qos[0]["durability"] == 1 and qos[0]["depth"] == 1  # transient local: rviz gets it
    for msg in bag.decoded("/tf"):
        assert [(t.header.frame_id, t.child_frame_id) for t in msg.transforms] == \
            [("base", "tool0")]


def load_yaml_string(text: str):
    from ruamel.yaml import YAML

    return YAML(typ="safe").load(text)


@pytest.mark.parametrize("distro", ["humble", "jazzy"])
def test_schemas_are_the_distributions_definitions(tmp_path, distro):
    out = tmp_path / "bag"
    export_recording(SAMPLE_RECORDING, out, ExportOptions(distro=distro))
    bag = read_bag(out)
    assert bag.metadata["version"] == R.DISTROS[distro].metadata_version
    store = R.typestore(distro)
    for name, (_, text) in bag.schemas.items():
        parsed = schema_types(text, name)
        assert parsed == store_types(store, name), name
        for other in R.DISTROS:  # the fields are the same in both distributions
            theirs = store_types(R.typestore(other), name)
            assert {k: [f for f in v if "=" not in f] for k, v in parsed.items()} == \
                {k: [f for f in v if "=" not in f] for k, v in theirs.items()}
    topics = {t["topic_metadata"]["name"]: t for t in bag.metadata["topics_with_message_count"]}
    for topic, (schema, _, _) in bag.channels.items():
        meta = topics[topic]["topic_metadata"]
        assert meta["type"] == schema and meta["serialization_format"] == "cdr"
        assert meta["type_description_hash"] == store.hash_rihs01(schema)
        qos = meta["offered_qos_profiles"]
        assert isinstance(qos, str if distro == "humble" else list)  # v8 string, v9 list


def test_metadata_yaml_is_where_rosbag2_reads_it(sample_bag):
    meta = load_yaml(sample_bag / "metadata.yaml")["rosbag2_bagfile_information"]
    assert meta["storage_identifier"] == "mcap"
    (rel,) = meta["relative_file_paths"]
    assert (sample_bag / rel).is_file() and meta["files"][0]["path"] == rel
    bag = read_bag(sample_bag)
    times = [t for msgs in bag.messages.values() for t, _ in msgs]
    assert meta["message_count"] == len(times)
    assert meta["starting_time"]["nanoseconds_since_epoch"] == min(times)
    assert meta["duration"]["nanoseconds"] == max(times) - min(times)
    counts = {t["topic_metadata"]["name"]: t["message_count"]
              for t in meta["topics_with_message_count"]}
    assert counts == {t: len(m) for t, m in bag.messages.items()}
    custom = meta["custom_data"]
    assert custom["armstereo.robot"] == "ur5e" and custom["armstereo.recording_kind"] == "capture"
    assert meta["ros_distro"] == "humble"


def test_compressed_images_keep_the_recorded_bytes(tmp_path):
    out = tmp_path / "bag"
    export_recording(SAMPLE_RECORDING, out, ExportOptions(compressed=True,
                                                          camera_frame="camera_color_optical"))
    bag = read_bag(out)
    assert "/camera/image" not in bag.messages
    (img, _) = bag.decoded("/camera/image/compressed")
    assert img.format == "bgr8; png compressed bgr8"
    assert img.header.frame_id == "camera_color_optical"
    rec = Recording.open(SAMPLE_RECORDING)
    assert bytes(img.data) == rec.views[0]._image_data
    stamp = rec.views[0].timestamp_ns
    assert lookup_at(bag, "base", "camera_color_optical", stamp) is not None


def test_scan_pairs_keep_their_viewpoints(tmp_path):
    intr = small_intrinsics()
    src = tmp_path / "scan.mcap"
    views = synthetic_views(4, intr, depth=False)
    with RecordingWriter(src, metadata={"kind": "scan", "views": "ring:2"}) as w:
        w.write_calibration(intr, views[0]["frame"].timestamp_ns - 10)
        for v in views:
            w.write_view(v["view"], v["frame"], v["q"], JOINTS, v["T_base_flange"],
                         v["T_flange_camera"], settle_s=0.5)
        for k in range(2):
            w.write_pair(k, 2 * k, 2 * k + 1, 0.05, 0.05, "x", viewpoint=k)
    report = export_recording(src, tmp_path / "bag")
    assert report["kind"] == "scan"
    bag = read_bag(tmp_path / "bag")
    pairs = [json.loads(m.data) for m in bag.decoded("/capture/events")
             if json.loads(m.data)["event"] == "pair"]
    assert [p["viewpoint"] for p in pairs] == [0, 1]
    for v in views:
        T = lookup_at(bag, "base", "camera_optical", v["frame"].timestamp_ns)
        assert np.abs(T - v["T_base_flange"] @ v["T_flange_camera"]).max() < 1e-12


@pytest.fixture(scope="module")
def reconstruction(tmp_path_factory):
    rec = Recording.open(SAMPLE_RECORDING)
    out = tmp_path_factory.mktemp("recon")
    recon = reconstruct_pair(rec[0])
    return write_outputs(recon, out, "pair000")


def test_reconstruction_cloud_equals_the_ply(reconstruction, tmp_path):
    report = export_recording(reconstruction["mcap"], tmp_path / "bag")
    assert report["kind"] == "reconstruction"
    bag = read_bag(tmp_path / "bag")
    (cloud,) = bag.decoded("/points")
    assert cloud.header.frame_id == "base"
    xyz, bgr = _cloud(cloud)
    ply = read_ply(reconstruction["ply"])
    assert len(xyz) > 10_000
    assert np.array_equal(xyz, ply.points) and np.array_equal(bgr, ply.colors_bgr)
    assert cloud.is_dense
    for topic in ("/reconstruction/rectified_left", "/reconstruction/disparity",
                  "/reconstruction/depth"):
        assert len(bag.decoded(topic)) == 1


def test_scene_analysis_exports_clouds_and_markers(tmp_path):
    cloud = scan(default_truth(), spacing=0.004, noise=0.0003)
    analysis = analyze_scene(cloud)
    src = write_scene_mcap(tmp_path / "scene.mcap", analysis, cloud)
    report = export_recording(src, tmp_path / "bag")
    assert report["kind"] == "scene" and not report["skipped"] and not report["warnings"]
    bag = read_bag(tmp_path / "bag")
    xyz, _ = _cloud(bag.decoded("/points")[0])
    assert np.allclose(xyz, cloud.points.astype(np.float32))
    (objects,) = bag.decoded("/scene/objects")
    cubes = [m for m in objects.markers if m.type == 1]
    texts = [m for m in objects.markers if m.type == 9]
    assert len(cubes) == len(texts) == len(analysis.objects) >= 3
    for o, cube in zip(analysis.objects, cubes, strict=True):
        assert cube.ns == f"object/{o.id}" and cube.header.frame_id == "base"
        assert np.allclose([cube.pose.position.x, cube.pose.position.y, cube.pose.position.z],
                           o.center_m)
        assert np.allclose([cube.scale.x, cube.scale.y, cube.scale.z], o.size_m)
    heights, _ = _cloud(bag.decoded("/scene/height_map")[0])
    hm = analysis.height_map.heights
    assert len(heights) == np.isfinite(hm).sum()
    (occ,) = bag.decoded("/scene/occupancy")
    assert occ.type == 6 and len(occ.points) == (analysis.occupancy.grid == 100).sum()


def test_fusion_exports_the_mesh_as_a_triangle_list(tmp_path):
    rng = np.random.default_rng(0)
    mesh = Mesh(rng.random((30, 3)).astype(np.float32), rng.integers(0, 30, (40, 3)),
                rng.integers(0, 256, (30, 3)).astype(np.uint8))
    K = np.array([[300.0, 0, 159.5], [0, 300.0, 119.5], [0, 0, 1]])
    poses = [np.eye(4), np.eye(4)]
    poses[1][:3, 3] = (0.05, 0.0, 0.0)
    views = [ViewPose(k, 0, poses[k], K, (320, 240), 1_000 + k) for k in range(2)]
    src = write_fusion_mcap(tmp_path / "fusion.mcap", mesh, mesh.vertices[:5], mesh.colors[:5],
                            views, {"voxel_m": "0.002"})
    report = export_recording(src, tmp_path / "bag")
    assert report["kind"] == "fusion" and not report["warnings"]
    bag = read_bag(tmp_path / "bag")
    (marker,) = bag.decoded("/fusion/mesh")
    assert marker.type == 11 and marker.ns == "mesh" and marker.header.frame_id == "base"
    pts = np.array([[p.x, p.y, p.z] for p in marker.points])
    assert np.array_equal(pts, mesh.vertices[mesh.faces.reshape(-1)].astype(float))
    cols = np.array([[c.b, c.g, c.r] for c in marker.colors])
    assert np.allclose(cols * 255, mesh.colors[mesh.faces.reshape(-1)], atol=1e-3)
    (views_msg,) = bag.decoded("/fusion/views")
    assert {m.ns for m in views_msg.markers} == {"view_0", "view_1", "tour"}
    assert [stamp_ns(m.transforms[0].header.stamp) for m in bag.decoded("/tf")] == [1000, 1001]


def test_cli_export_prints_the_topics_and_refuses_to_overwrite(capsys, tmp_path):
    out = tmp_path / "bag"
    code, text, err = run(capsys, "export", SAMPLE_RECORDING, "--to", "ros2", "--out", out)
    assert code == 0 and not err
    assert "/camera/image" in text and "sensor_msgs/msg/Image" in text
    code, _, err = run(capsys, "export", SAMPLE_RECORDING, "--to", "ros2", "--out", out)
    assert code == 2 and len(err) == 1 and "--force" in err[0]
    code, _, err = run(capsys, "export", SAMPLE_RECORDING, "--to", "ros2", "--out", out,
                       "--force", "--json")
    assert code == 0
    other = tmp_path / "not_a_bag"
    other.mkdir()
    (other / "keep.txt").write_text("mine")
    code, _, err = run(capsys, "export", SAMPLE_RECORDING, "--to", "ros2", "--out", other,
                       "--force")
    assert code == 2 and "not a ROS 2 bag folder" in err[0]
    assert (other / "keep.txt").read_text() == "mine"
