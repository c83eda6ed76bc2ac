"""The depth filter: weights follow each pixel's local noise, the fit averages noise on a
surface without blending the two sides of a depth edge, and slivers are dropped."""

import dataclasses

import numpy as np
import pytest

from armstereo.errors import ConfigError
from armstereo.fusion.depth_filter import DepthFilterOptions, filter_frame, fit_depth
from armstereo.fusion.tsdf import DepthFrame

F = 300.0


def _plane_depth(h=60, w=80, z0=0.5, tilt=0.2):
    """Exact z-depth of a tilted plane seen by a pinhole (1/z linear in u, v)."""
    v, u = np.mgrid[0:h, 0:w].astype(float)
    q = 1.0 / z0 + tilt * (u - w / 2) / (F * z0)
    return (1.0 / q).astype(np.float32)


def test_an_exact_plane_keeps_its_depth_and_full_weight():
    z = _plane_depth()
    fit, weight = fit_depth(z, DepthFilterOptions())
    inner = np.s_[10:-10, 10:-10]
    assert np.nanmax(np.abs(fit[inner] - z[inner])) < 1e-6
    assert weight[inner].min() > 0.99


def test_noise_is_averaged_and_weighted_by_its_size():
    rng = np.random.default_rng(0)
    z = _plane_depth()
    quiet = z + rng.normal(0, 0.0005, z.shape).astype(np.float32)
    noisy = z + rng.normal(0, 0.004, z.shape).astype(np.float32)
    o = DepthFilterOptions()
    inner = np.s_[10:-10, 10:-10]
    for d in (quiet, noisy):
        fit, _ = fit_depth(d, o)
        # 225 pixels in the window: the fit's error is several times below the pixels'
        # (a pixel whose own noise puts it an edge away from most neighbours is dropped)
        assert np.mean(np.isnan(fit[inner])) < 0.01
        assert np.nanstd(fit[inner] - z[inner]) < 0.3 * np.std(d[inner] - z[inner])
    w_quiet = np.median(fit_depth(quiet, o)[1][inner])
    w_noisy = np.median(fit_depth(noisy, o)[1][inner])
    # inverse variance with a 1 mm floor: 1 / (1 + 0.25) and 1 / (1 + 16)
    assert w_quiet == pytest.approx(0.8, abs=0.05)
    assert w_noisy == pytest.approx(1 / 17, rel=0.2)


def test_a_depth_edge_is_not_blended_but_weighted_down():
    z = np.full((60, 80), 0.5, np.float32)
    z[:, 40:] = 0.45  # a 50 mm step
    fit, weight = fit_depth(z, DepthFilterOptions())
    assert np.nanmax(np.abs(fit - z)) < 1e-6  # each side keeps its own depth
    assert weight[30, 39] < 0.01 and weight[30, 40] < 0.01  # next to the edge: unreliable
    assert weight[30, 10] > 0.99 and weight[30, 70] > 0.99  # a window away: full weight


def test_specks_are_dropped():
    z = np.full((60, 80), np.nan, np.float32)
    z[20:23, 20:23] = 0.5  # 9 pixels: below a quarter of the 15 x 15 window
    z[30:50, 40:70] = 0.5
    fit, weight = fit_depth(z, DepthFilterOptions())
    assert np.all(np.isnan(fit[20:23, 20:23])) and np.all(weight[20:23, 20:23] == 0)
    assert np.all(np.isfinite(fit[30:50, 40:70]))


def test_filter_frame_sets_depth_and_weight_or_leaves_the_frame():
    rng = np.random.default_rng(1)
    depth = _plane_depth() + rng.normal(0, 0.002, (60, 80)).astype(np.float32)
    K = np.array([[F, 0, 40.0], [0, F, 30.0], [0, 0, 1]])
    frame = DepthFrame(depth, K, np.eye(4))
    assert filter_frame(frame, DepthFilterOptions(enabled=False)) is frame
    smoothed = filter_frame(frame, DepthFilterOptions())
    assert smoothed.weight is not None and not np.allclose(smoothed.depth, depth,
                                                          equal_nan=True)
    weighted = filter_frame(frame, DepthFilterOptions(smooth=False))
    keep = np.isfinite(weighted.depth)
    assert np.array_equal(weighted.depth[keep], depth[keep])
    np.testing.assert_array_equal(weighted.weight, smoothed.weight)


@pytest.mark.parametrize("bad", [dict(window=4), dict(window=1), dict(sigma0=0.0),
                                 dict(edge=-1.0), dict(min_support=0.0),
                                 dict(min_support=1.5), dict(sigma0=float("nan"))])
def test_bad_options_are_config_errors(bad):
    with pytest.raises(ConfigError):
        DepthFilterOptions(**bad)


def test_options_are_recorded():
    o = DepthFilterOptions(window=11)
    assert o.record() == dataclasses.asdict(o) and o.record()["window"] == 11


def test_noise_where_the_map_is_rough_fuses_better_with_the_filter():
    # Exact depth of four views, with 4 mm noise on the left half of every image (a weakly
    # textured surface) and 0.3 mm elsewhere: weighting by the local residual and fitting
    # must beat fusing every pixel with weight 1 (measured: 0.37 against 0.63 mm).
    from armstereo.fusion.mesh import extract_mesh
    from armstereo.fusion.metrics import point_accuracy
    from armstereo.fusion.tsdf import TsdfVolume
    from tests.armstereo.fusion.synthetic import ROI, ring_frames

    frames, truth = ring_frames(4)
    rng = np.random.default_rng(2)
    noisy = []
    for f in frames:
        sigma = np.where(np.arange(f.depth.shape[1]) < f.depth.shape[1] // 2, 0.004, 0.0003)
        noise = rng.normal(0, 1, f.depth.shape) * sigma[None, :]
        noisy.append(dataclasses.replace(f, depth=(f.depth + noise).astype(np.float32)))

    def accuracy_mm(fs, min_weight):
        volume = TsdfVolume(ROI, 0.002, 0.008, behind=0.004)
        for f in fs:
            volume.integrate(f)
        mesh = extract_mesh(volume, min_weight)
        tri = mesh.vertices[mesh.faces].astype(float)
        return point_accuracy(tri.mean(axis=1), truth, mesh.triangle_areas()).accuracy_mean_mm

    o = DepthFilterOptions()
    plain = accuracy_mm(noisy, 1.0)
    filtered = accuracy_mm([filter_frame(f, o) for f in noisy], 0.02)
    assert filtered < 0.75 * plain
