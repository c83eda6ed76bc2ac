"""The fusion MCAP: the hand-encoded triangle list equals protobuf's own, and the file reads."""

import numpy as np
from foxglove_schemas_protobuf.Color_pb2 import Color
from foxglove_schemas_protobuf.FrameTransforms_pb2 import FrameTransforms
from foxglove_schemas_protobuf.Point3_pb2 import Point3
from foxglove_schemas_protobuf.PointCloud_pb2 import PointCloud
from foxglove_schemas_protobuf.SceneUpdate_pb2 import SceneUpdate
from foxglove_schemas_protobuf.TriangleListPrimitive_pb2 import TriangleListPrimitive
from mcap.reader import make_reader

from armstereo.fusion.foxglove import (
    TOPIC_MESH,
    TOPIC_POINTS,
    TOPIC_TF,
    TOPIC_VIEWS,
    ViewPose,
    triangle_list,
    write_fusion_mcap,
)
from armstereo.fusion.mesh import Mesh


def _mesh(n=300, m=500, seed=0) -> Mesh:
    rng = np.random.default_rng(seed)
    return Mesh((rng.random((n, 3)) - 0.5).astype(np.float32), rng.integers(0, n, (m, 3)),
                rng.integers(0, 256, (n, 3)).astype(np.uint8))


def test_triangle_list_equals_the_protobuf_built_one():
    mesh = _mesh()
    fast = triangle_list(mesh)
    slow = TriangleListPrimitive(pose=fast.pose, color=fast.color)
    slow.points.extend(Point3(x=x, y=y, z=z) for x, y, z in mesh.vertices.astype(float))
    slow.colors.extend(Color(r=c[2] / 255, g=c[1] / 255, b=c[0] / 255, a=1.0)
                       for c in mesh.colors.astype(float))
    slow.indices.extend(mesh.faces.reshape(-1).tolist())
    assert fast == slow
    assert fast.pose.orientation.w == 1.0


def test_empty_mesh_encodes():
    assert len(triangle_list(Mesh.empty()).points) == 0


def test_fusion_mcap_contents(tmp_path):
    mesh = _mesh()
    T = np.eye(4)
    T[:3, 3] = (0.1, 0.2, 0.5)
    K = np.array([[300.0, 0, 159.5], [0, 300.0, 119.5], [0, 0, 1]])
    views = [ViewPose(1, 0, T, K, (320, 240), 2_000), ViewPose(0, 0, T, K, (320, 240), 1_000)]
    pts = mesh.vertices[:10]
    path = write_fusion_mcap(tmp_path / "f.mcap", mesh, pts, mesh.colors[:10], views,
                             {"voxel_m": "0.002"})
    got = {}
    with open(path, "rb") as f:
        for _schema, channel, message in make_reader(f).iter_messages():
            got.setdefault(channel.topic, []).append((message.log_time, message.data))
        f.seek(0)
        meta = {m.name: m.metadata for m in make_reader(f).iter_metadata()}
    assert meta["armstereo"]["voxel_m"] == "0.002"
    update = SceneUpdate.FromString(got[TOPIC_MESH][0][1])
    tri = update.entities[0].triangles[0]
    assert update.entities[0].frame_id == "base" and len(tri.points) == 300
    assert list(tri.indices) == mesh.faces.reshape(-1).tolist()
    cloud = PointCloud.FromString(got[TOPIC_POINTS][0][1])
    xyz = np.frombuffer(cloud.data, dtype=np.float32).reshape(-1, 4)[:, :3]
    np.testing.assert_array_equal(xyz, pts)
    views_update = SceneUpdate.FromString(got[TOPIC_VIEWS][0][1])
    assert [e.id for e in views_update.entities] == ["view_0", "view_1", "tour"]
    assert views_update.entities[0].texts[0].text == "view 0 (pair 0)"
    assert [t for t, _ in got[TOPIC_TF]] == [1_000, 2_000]  # the tour in time order
    tf = FrameTransforms.FromString(got[TOPIC_TF][0][1]).transforms[0]
    assert (tf.parent_frame_id, tf.child_frame_id) == ("base", "camera_optical")
    assert tf.translation.z == 0.5
    # scene entities are stamped at the start, so they show during the whole playback
    assert got[TOPIC_MESH][0][0] == got[TOPIC_VIEWS][0][0] == 1_000
