"""Mesh extraction's mask, view support and colours, and the mesh PLY round trip."""

import numpy as np
import pytest
from skimage.measure import marching_cubes

from armstereo.errors import ConfigError, StereoError
from armstereo.fusion.mesh import UNSEEN_BGR, Mesh, cube_mask, extract_mesh, view_support
from armstereo.fusion.mesh_ply import encode_mesh_ply, read_mesh_ply, write_mesh_ply
from armstereo.fusion.tsdf import DepthFrame, Roi, TsdfVolume


def _down_camera(z: float) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = np.diag([1.0, -1.0, -1.0])  # optical z = -base z
    T[2, 3] = z
    return T


def _plane(z_camera=0.5, size=(200, 160), image=None) -> DepthFrame:
    w, h = size
    K = np.array([[100.0, 0, (w - 1) / 2], [0, 100.0, (h - 1) / 2], [0, 0, 1]])
    return DepthFrame(np.full((h, w), z_camera, np.float32), K, _down_camera(z_camera), image)


def _plane_volume() -> TsdfVolume:
    volume = TsdfVolume(Roi((-0.05, -0.05, -0.05), (0.05, 0.05, 0.05)), 0.005, 0.0125)
    volume.integrate(_plane())
    return volume


def test_scikit_image_reads_a_cube_from_its_far_corner():
    # The fact cube_mask relies on: mask[i] enables the cube from i - 1 to i on every axis.
    vol = np.broadcast_to(2.5 - np.arange(6.0), (6, 6, 6)).copy()  # plane at index 2.5
    for idx, faces in (((3, 3, 3), 2), ((2, 2, 2), 0)):
        mask = np.zeros(vol.shape, bool)
        mask[idx] = True
        try:
            verts, f, _, _ = marching_cubes(vol, 0.0, mask=mask)
        except RuntimeError:
            f = []
        assert len(f) == faces
    verts, _, _, _ = marching_cubes(vol, 0.0, mask=np.pad(np.ones((1, 1, 1), bool),
                                                          ((3, 2), (3, 2), (3, 2))))
    assert verts.min(axis=0).tolist() == [2.0, 2.0, 2.5]


def test_the_observed_mask_alone_makes_a_ghost_behind_the_surface():
    # Why cube_mask exists: with mask = observed, cubes between the band behind the surface
    # and unseen space produce a second sheet (measured below the plane z = 0).
    volume = _plane_volume()
    observed = volume.observed(1.0)
    verts, _, _, _ = marching_cubes(volume.tsdf, 0.0, mask=observed)
    z = volume.voxel_points(verts)[:, 2]
    assert z.min() < -0.005
    mesh = extract_mesh(volume)
    np.testing.assert_allclose(mesh.vertices[:, 2], 0.0, atol=1e-6)


def test_cube_mask_needs_all_eight_corners():
    observed = np.ones((4, 4, 4), bool)
    observed[2, 1, 3] = False
    mask = cube_mask(observed)
    # 3 x 3 x 3 cubes; the four that share the corner (low corners i 1..2, j 0..1, k 2) go,
    # each marked at its far corner.
    assert mask.sum() == 27 - 4
    assert not mask[0].any() and not mask[:, 0].any() and not mask[:, :, 0].any()
    for far in ((2, 1, 3), (2, 2, 3), (3, 1, 3), (3, 2, 3)):
        assert not mask[far]


def test_faces_wind_towards_the_cameras():
    mesh = extract_mesh(_plane_volume())
    a, b, c = (mesh.vertices[mesh.faces[:, i]] for i in range(3))
    normals = np.cross(b - a, c - a)
    assert np.all(normals[:, 2] > 0)  # the camera is above: faces are counter-clockwise from it


def test_view_support_counts_frames_and_averages_colours():
    w, h = 200, 160
    red = np.zeros((h, w, 3), np.uint8)
    red[..., 2] = 200
    blue = np.zeros((h, w, 3), np.uint8)
    blue[..., 0] = 100
    frames = [_plane(image=red), _plane(image=blue), _plane(0.7)]
    points = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 0.05], [5.0, 0.0, 0.0]])
    s = view_support(points, frames, tolerance=0.01)
    assert s.views.tolist() == [3, 0, 0]
    assert s.per_frame.tolist() == [1, 1, 1]
    assert s.colors[0].tolist() == [50, 0, 100]  # mean of the two coloured frames (BGR)
    assert s.colors[1].tolist() == list(UNSEEN_BGR)
    with pytest.raises(ConfigError):
        view_support(points, frames, tolerance=0.0)


def _mesh() -> Mesh:
    rng = np.random.default_rng(0)
    return Mesh(rng.random((7, 3)).astype(np.float32), np.array([[0, 1, 2], [2, 3, 4], [4, 5, 6]]),
                rng.integers(0, 256, (7, 3)).astype(np.uint8))


def test_mesh_ply_round_trip(tmp_path):
    mesh = _mesh()
    path = write_mesh_ply(tmp_path / "mesh.ply", mesh, comment="frame base, metres")
    back = read_mesh_ply(path)
    np.testing.assert_array_equal(back.vertices, mesh.vertices)
    np.testing.assert_array_equal(back.faces, mesh.faces)
    np.testing.assert_array_equal(back.colors, mesh.colors)
    header = path.read_bytes().split(b"end_header\n")[0].decode()
    assert "element face 3\nproperty list uchar int vertex_indices" in header
    assert "comment frame base, metres" in header
    assert len(read_mesh_ply(write_mesh_ply(tmp_path / "e.ply", Mesh.empty()))) == 0


def test_mesh_ply_body_is_little_endian_rgb_then_faces():
    mesh = _mesh()
    data = encode_mesh_ply(mesh)
    body = data.split(b"end_header\n", 1)[1]
    first = np.frombuffer(body[:15], dtype="<f4", count=3)
    np.testing.assert_array_equal(first, mesh.vertices[0])
    assert list(body[12:15]) == mesh.colors[0, ::-1].tolist()  # RGB in the file
    face0 = body[7 * 15:7 * 15 + 13]
    assert face0[0] == 3 and np.frombuffer(face0[1:], "<i4").tolist() == [0, 1, 2]


def test_read_mesh_ply_refuses_other_layouts(tmp_path):
    bad = tmp_path / "bad.ply"
    bad.write_bytes(b"ply\nformat ascii 1.0\nelement vertex 0\nend_header\n")
    with pytest.raises(StereoError, match="layout"):
        read_mesh_ply(bad)
    cut = tmp_path / "cut.ply"
    cut.write_bytes(encode_mesh_ply(_mesh())[:-5])
    with pytest.raises(StereoError, match="truncated"):
        read_mesh_ply(cut)


def test_mesh_rejects_bad_indices():
    with pytest.raises(ConfigError, match="exist"):
        Mesh(np.zeros((3, 3)), np.array([[0, 1, 3]]), np.zeros((3, 3), np.uint8))


def test_fused_cloud_keeps_what_two_pairs_confirm():
    from armstereo.fusion.mesh import fused_cloud
    from tests.armstereo.fusion.synthetic import ROI, ring_frames

    frames, _ = ring_frames(2)  # two views from opposite sides: object sides seen once
    volume = TsdfVolume(ROI, 0.004, 0.016)
    for f in frames:
        volume.integrate(f)
    mesh = extract_mesh(volume)
    coloured, points, colors, support = fused_cloud(mesh, frames, tolerance=0.008)
    assert len(points) == np.count_nonzero(support.views >= 2) == len(colors)
    single = np.count_nonzero(support.views == 1)
    assert 0.05 * len(mesh.vertices) < single < 0.6 * len(mesh.vertices)
    for f in frames:  # every kept point lies on both depth maps
        u, v, z = f.project(points)
        d = f.depth[np.rint(v).astype(int), np.rint(u).astype(int)]
        assert np.all(np.abs(d - z) <= 0.008)
    assert (coloured.colors != 128).all(axis=1).mean() > 0.9
    with pytest.raises(ConfigError):
        fused_cloud(mesh, frames, 0.008, min_views=0)
