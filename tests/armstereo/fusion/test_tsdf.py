"""TSDF integration: exact depth maps fuse to the exact surface, and the conventions that
silently bias a fused surface (pixel centres, weight threshold, the marching-cubes mask) are
caught by numbers, not by looking."""

import numpy as np
import pytest

from armstereo.errors import ConfigError
from armstereo.fusion.mesh import extract_mesh
from armstereo.fusion.metrics import mesh_distance, point_accuracy, thin
from armstereo.fusion.roi import frame_points
from armstereo.fusion.tsdf import DepthFrame, Roi, TsdfVolume
from tests.armstereo.fusion.synthetic import ROI, ring_frames

VOXEL = 0.002
TRUNC = 4 * VOXEL
ACCURACY_GATE_MM = 0.15  # the gate for exact depth at 2 mm voxels
COMPLETENESS_GATE = 0.97  # share of the seen surface within 2 mm of the mesh


def _fuse(frames, *, interpolation="bilinear", min_weight=1.0):
    volume = TsdfVolume(ROI, VOXEL, TRUNC, interpolation=interpolation)
    for f in frames:
        volume.integrate(f)
    return extract_mesh(volume, min_weight)


def _accuracy_mm(mesh, truth) -> float:
    tri = mesh.vertices[mesh.faces].astype(float)
    return point_accuracy(tri.mean(axis=1), truth, mesh.triangle_areas()).accuracy_mean_mm


def _completeness(mesh, frames) -> float:
    """Share of the surface the frames saw (inside the ROI) within 2 mm of the mesh."""
    seen = np.concatenate([frame_points(f, 40_000) for f in frames])
    seen = thin(seen[ROI.contains(seen)], 0.002)
    d = mesh_distance(mesh.vertices[mesh.faces].astype(float), seen)
    return float(np.mean(d <= 0.002))


@pytest.fixture(scope="module")
def exact():
    return ring_frames(8)


def test_exact_depth_fuses_to_the_true_surface(exact):
    frames, truth = exact
    mesh = _fuse(frames)
    assert _accuracy_mm(mesh, truth) <= ACCURACY_GATE_MM
    assert _completeness(mesh, frames) >= COMPLETENESS_GATE


def test_bilinear_lookup_beats_nearest_pixel(exact):
    # Both are unbiased; nearest-pixel depth is off by up to half a pixel of slope on slanted
    # surfaces, which the average does not remove (measured: 0.12 vs 0.16 mm here).
    frames, truth = exact
    assert _accuracy_mm(_fuse(frames), truth) < 0.9 * _accuracy_mm(
        _fuse(frames, interpolation="nearest"), truth)


def test_a_half_pixel_slip_fails_the_accuracy_gate():
    # Telling the fusion the principal point is half a pixel off is exactly what integrating
    # OpenCV depth with a pixel-corner convention (u covers [u, u+1)) does.
    # (measured: 0.47 mm against 0.12 mm with the right convention)
    frames, truth = ring_frames(8, cx_shift=0.5, cy_shift=0.5)
    assert _accuracy_mm(_fuse(frames), truth) > 2 * ACCURACY_GATE_MM


def test_a_weight_threshold_above_one_view_loses_surface(exact):
    # Surfaces seen by few views (object sides, the table's edges of the ROI) vanish when the
    # mesh needs three observations, as with Open3D's default weight_threshold of 3.
    frames, _ = exact
    assert _completeness(_fuse(frames, min_weight=3.0), frames) < COMPLETENESS_GATE


def test_a_surface_seen_once_is_meshed():
    frames, truth = ring_frames(1)
    mesh = _fuse(frames)
    assert mesh.area() > 0.05  # most of the 0.4 m x 0.4 m table part in view
    assert _accuracy_mm(mesh, truth) < ACCURACY_GATE_MM
    assert len(_fuse(frames, min_weight=2.0)) == 0


def _plane_frame(z_camera: float = 0.5, size=(64, 48)) -> DepthFrame:
    """A camera looking straight down at the plane z = 0 of base from ``z_camera``."""
    T = np.eye(4)
    T[:3, :3] = np.diag([1.0, -1.0, -1.0])  # optical z = -base z
    T[2, 3] = z_camera
    w, h = size
    K = np.array([[100.0, 0, (w - 1) / 2], [0, 100.0, (h - 1) / 2], [0, 0, 1]])
    return DepthFrame(np.full((h, w), z_camera, np.float32), K, T)


def test_voxels_beyond_the_truncation_band_stay_unseen():
    roi = Roi((-0.05, -0.05, -0.05), (0.05, 0.05, 0.05))
    volume = TsdfVolume(roi, 0.005, 0.01)
    volume.integrate(_plane_frame())
    z = volume.voxel_points(np.array([[0, 0, k] for k in range(volume.shape[2])]))[:, 2]
    seen = volume.weight[10, 10] > 0
    band_edge = np.isclose(z, -0.01)  # exactly -trunc: either side, by rounding
    assert np.all(seen[(z > -0.01) & ~band_edge]) and not np.any(seen[(z < -0.01) & ~band_edge])
    tsdf = volume.tsdf[10, 10]
    np.testing.assert_allclose(tsdf[seen], np.clip(z[seen] / 0.01, -1, 1), atol=1e-6)


def test_a_shorter_band_behind_the_surface_leaves_the_rest_unseen():
    roi = Roi((-0.05, -0.05, -0.05), (0.05, 0.05, 0.05))
    volume = TsdfVolume(roi, 0.005, 0.01, behind=0.005)
    volume.integrate(_plane_frame())
    z = volume.voxel_points(np.array([[0, 0, k] for k in range(volume.shape[2])]))[:, 2]
    seen = volume.weight[10, 10] > 0
    edge = np.isclose(z, -0.005)
    assert np.all(seen[(z > -0.005) & ~edge]) and not np.any(seen[(z < -0.005) & ~edge])
    # values stay in units of the (front) truncation
    np.testing.assert_allclose(volume.tsdf[10, 10][seen], np.clip(z[seen] / 0.01, -1, 1),
                               atol=1e-6)


@pytest.mark.parametrize("behind", [0.001, 0.02, float("nan")])
def test_the_band_behind_must_lie_between_a_voxel_and_the_truncation(behind):
    with pytest.raises(ConfigError, match="behind"):
        TsdfVolume(ROI, 0.002, 0.008, behind=behind)


def test_no_ghost_surface_behind_a_single_view():
    # Behind the band the volume is unobserved; a cube mixing the band's negative values with
    # the unobserved default would put a second sheet at z = -trunc.
    roi = Roi((-0.05, -0.05, -0.05), (0.05, 0.05, 0.05))
    volume = TsdfVolume(roi, 0.005, 0.01)
    volume.integrate(_plane_frame(size=(200, 160)))
    mesh = extract_mesh(volume)
    assert len(mesh) > 0
    np.testing.assert_allclose(mesh.vertices[:, 2], 0.0, atol=1e-6)


def test_empty_or_unseen_volume_gives_an_empty_mesh():
    roi = Roi((-0.05, -0.05, 1.0), (0.05, 0.05, 1.1))  # above the camera: never seen
    volume = TsdfVolume(roi, 0.005, 0.01)
    assert volume.integrate(_plane_frame()) == 0
    assert len(extract_mesh(volume)) == 0


@pytest.mark.parametrize("text", ["1,2,3", "0,1,0,1,1,0", "a,b,c,d,e,f", "0,1,0,1,0,nan"])
def test_roi_parse_rejects_malformed_boxes(text):
    with pytest.raises(ConfigError, match="--roi"):
        Roi.parse(text)


def test_roi_grid_covers_the_box():
    roi = Roi.parse("0,0.1,0,0.05,0,0.011")
    assert roi.grid_shape(0.01) == (11, 6, 3)
    assert roi.as_list() == [0, 0.1, 0, 0.05, 0, 0.011]


def test_bad_volume_options_are_config_errors():
    with pytest.raises(ConfigError, match="--voxel"):
        TsdfVolume(ROI, 0.0, 0.01)
    with pytest.raises(ConfigError, match="--trunc"):
        TsdfVolume(ROI, 0.002, 0.001)
    with pytest.raises(ConfigError, match="voxels"):
        TsdfVolume(Roi((0, 0, 0), (10, 10, 10)), 0.001, 0.004)


def test_depth_frame_checks_its_inputs():
    f = _plane_frame()
    with pytest.raises(ConfigError, match="K"):
        DepthFrame(f.depth, np.eye(3) * 2, f.T_base_camera)
    T = f.T_base_camera.copy()
    T[0, 0] = 2.0
    with pytest.raises(ConfigError, match="rigid"):
        DepthFrame(f.depth, f.K, T)
    with pytest.raises(ConfigError, match="differ"):
        DepthFrame(f.depth, f.K, f.T_base_camera, np.zeros((2, 2, 3), np.uint8))


def test_per_pixel_weights_decide_the_mean_and_weight_zero_is_unseen():
    # Two maps of the plane z = 0 from the same camera, one 2 mm deeper with weight 3: the
    # fused zero crossing is their weighted mean, 1.5 mm below the plane; the half of the
    # second map with weight 0 adds nothing there.
    roi = Roi((-0.02, -0.02, -0.01), (0.02, 0.02, 0.01))
    volume = TsdfVolume(roi, 0.001, 0.008)
    a = _plane_frame()
    w = np.full(a.depth.shape, 3.0, np.float32)
    w[:, : a.depth.shape[1] // 2] = 0.0
    b = DepthFrame(a.depth + np.float32(0.002), a.K, a.T_base_camera, weight=w)
    volume.integrate(a)
    volume.integrate(b)
    z = volume.voxel_points(np.array([[0, 0, k] for k in range(volume.shape[2])]))[:, 2]
    j = volume.shape[1] // 2

    def zero_crossing(i):
        seen = volume.weight[i, j] > 0
        return np.interp(0.0, volume.tsdf[i, j][seen] * volume.trunc, z[seen])

    i = volume.shape[0] - 5  # +x: the weighted half of the second map
    assert zero_crossing(i) == pytest.approx(-0.0015, abs=1e-4)
    assert volume.weight[i, j, np.argmin(np.abs(z))] == pytest.approx(4.0)
    assert zero_crossing(4) == pytest.approx(0.0, abs=1e-4)
    assert volume.weight[4, j, np.argmin(np.abs(z))] == pytest.approx(1.0)


def test_depth_frame_checks_its_weights():
    f = _plane_frame()
    for bad in (np.ones((2, 2), np.float32), -np.ones_like(f.depth),
                np.full_like(f.depth, np.nan)):
        with pytest.raises(ConfigError, match="weight"):
            DepthFrame(f.depth, f.K, f.T_base_camera, weight=bad)
