"""reconstruct_views: images + poses from anywhere -> a base-frame cloud on the true surface."""

import numpy as np
import pytest

from armstereo import reconstruct_views
from armstereo.errors import ConfigError, StereoError
from armstereo.kinematics import ArmModel
from armstereo.mount import CameraMount
from armstereo.reconstruct.stereo_options import SgbmOptions
from armstereo.transforms import make_T
from drivers.mock.scene import default_table_scene
from drivers.mock.start_poses import table_start

BASELINE_M = 0.08


@pytest.fixture(scope="module")
def views():
    """Two renders of the table scene 8 cm apart along camera x, with their exact poses."""
    model = ArmModel.load("ur5e", mount=CameraMount.load(None))
    scene = default_table_scene(0)
    T1 = model.camera_pose(table_start(model))
    T2 = T1 @ make_T(np.eye(3), [BASELINE_M, 0.0, 0.0])
    intr = model.mount.intrinsics
    (img1, _), (img2, _) = (scene.render(T, intr) for T in (T1, T2))
    return img1, img2, intr.K, T1, T2, scene.truth()


def test_points_lie_on_the_true_surface_in_the_base_frame(views):
    img1, img2, K, T1, T2, truth = views
    result = reconstruct_views(img1, img2, K, K, np.round(T1, 6), np.round(T2, 6))
    assert result.points.shape[1] == 3 and len(result.points) > 200_000
    assert result.colors.dtype == np.uint8 and result.colors.shape == result.points.shape
    assert np.array_equal(result.colors, result.colors_bgr[:, ::-1])
    distance = truth.distance(result.points)
    assert np.median(distance) < 0.12e-3  # measured 0.104 mm
    assert np.mean(distance < 2e-3) > 0.965  # measured 0.973 (misses: occlusion edges)
    assert not result.swapped and result.disparity.dtype == np.float32


def test_either_order_gives_the_same_cloud(views):
    img1, img2, K, T1, T2, _ = views
    a = reconstruct_views(img1, img2, K, K, T1, T2)
    b = reconstruct_views(img2, img1, K, K, T2, T1)
    assert b.swapped and not a.swapped
    assert np.array_equal(a.points, b.points)


def test_disparity_bounds_are_another_way_to_say_the_depth_range(views):
    img1, img2, K, T1, T2, _ = views
    f_b = K[0, 0] * BASELINE_M  # rectified focal length equals the input's here
    by_depth = reconstruct_views(img1, img2, K, K, T1, T2, near=0.35, far=0.7)
    by_disp = reconstruct_views(img1, img2, K, K, T1, T2, min_disparity=f_b / 0.7,
                                max_disparity=f_b / 0.35)
    assert by_disp.window.near == pytest.approx(by_depth.window.near, rel=1e-6)
    assert by_disp.window.far == pytest.approx(by_depth.window.far, rel=1e-6)


@pytest.mark.parametrize("kwargs,error,message", [
    ({"method": "magic"}, ConfigError, "--method"),
    ({"near": 0.4, "max_disparity": 100}, ConfigError, "not both"),
    ({"min_disparity": -1}, ConfigError, "min_disparity must be >= 0"),
])
def test_bad_options_are_refused(views, kwargs, error, message):
    img1, img2, K, T1, T2, _ = views
    with pytest.raises(error, match=message):
        reconstruct_views(img1, img2, K, K, T1, T2, **kwargs)


def test_bad_poses_are_refused(views):
    img1, img2, K, T1, _, _ = views
    with pytest.raises(StereoError, match="T_base_cam2 is not a rigid transform"):
        reconstruct_views(img1, img2, K, K, T1, np.diag([1.0, 1.0, -1.0, 1.0]))
    with pytest.raises(StereoError):
        reconstruct_views(img1, img2, K, K, T1, T1)  # no baseline


def test_the_pair_is_planned_once(views, monkeypatch):
    """The poses are checked and the rectification solved once per pair, not once for the
    depth range and again for the images."""
    from armstereo.reconstruct import rectify

    calls = {"solve": 0, "as_rigid": 0}

    def counted(name, real):
        def spy(*args, **kwargs):
            calls[name] += 1
            return real(*args, **kwargs)
        return spy

    monkeypatch.setattr(rectify, "_solve", counted("solve", rectify._solve))
    monkeypatch.setattr(rectify, "as_rigid", counted("as_rigid", rectify.as_rigid))
    img1, img2, K, T1, T2, _ = views
    reconstruct_views(img1, img2, K, K, T1, T2, stereo=SgbmOptions())
    assert calls == {"solve": 1, "as_rigid": 2}
