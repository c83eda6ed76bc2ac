"""The uncalibrated path on real photographs (temple ring) and on the mock scene."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from armstereo.epipolar.errors import EpipolarError
from armstereo.epipolar.fundamental import fundamental_from_poses
from armstereo.epipolar.metrics import sampson_distance
from armstereo.epipolar.uncalibrated import (
    estimate_from_images,
    reconstruct_images,
    rectify_uncalibrated,
)
from armstereo.errors import ConfigError
from armstereo.transforms import invert, make_T

from .mock_views import LATERAL, model, start_pose

DATA = Path(__file__).resolve().parents[2] / "data" / "temple_ring"
NEIGHBOURS = [("0008", "0009"), ("0009", "0010")]


def temple_cameras() -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """name -> (K, T_world_cam) from the published ``K [R | t]`` (world -> camera)."""
    cams = {}
    for line in (DATA / "templeSR_par.txt").read_text().splitlines()[1:]:
        name, *values = line.split()
        v = np.array(values, float)
        cams[name] = (v[:9].reshape(3, 3), invert(make_T(v[9:18].reshape(3, 3), v[18:])))
    return cams


def temple(a: str, b: str):
    cams = temple_cameras()
    na, nb = f"templeSR{a}.png", f"templeSR{b}.png"
    F_true = fundamental_from_poses(cams[na][0], cams[nb][0], cams[na][1], cams[nb][1])
    return cv2.imread(str(DATA / na)), cv2.imread(str(DATA / nb)), F_true, cams[na], cams[nb]


@pytest.mark.parametrize("detector", ["sift", "harris"])
@pytest.mark.parametrize("a, b", NEIGHBOURS)
def test_image_F_agrees_with_the_published_cameras(a, b, detector):
    im1, im2, F_true, _, _ = temple(a, b)
    F, x1, x2 = estimate_from_images(im1, im2, detector=detector)
    assert len(x1) >= 30
    assert np.median(sampson_distance(F_true, x1, x2)) < 1.0
    assert np.median(sampson_distance(F, x1, x2)) < 0.5


@pytest.mark.parametrize("a, b", NEIGHBOURS)
def test_hartley_rectification_aligns_rows(a, b):
    im1, im2, _, _, _ = temple(a, b)
    F, x1, x2 = estimate_from_images(im1, im2)
    r = rectify_uncalibrated(im1, im2, F, x1, x2)
    assert r.median_abs_dy_px < 0.5
    pl, pr = r.rectified_matches()
    assert np.median(np.abs(pl[:, 1] - pr[:, 1])) == pytest.approx(r.median_abs_dy_px)
    d = pl[:, 0] - pr[:, 0]
    assert d.min() >= 0  # positive disparities: the left view is the left one
    assert r.left.shape == r.right.shape and r.left_mask.shape == r.left.shape[:2]
    J = np.linalg.det(r.H_left[:2, :2] - np.outer(r.H_left[:2, 2], r.H_left[2, :2]))
    assert J > 0  # not mirrored


def test_wide_pairs_fail_with_a_clear_error():
    im1, im2, _, _, _ = temple("0008", "0010")  # 46 degrees apart
    with pytest.raises(EpipolarError, match="undetermined"):
        estimate_from_images(im1, im2)


@pytest.mark.slow  # dense Birchfield-Tomasi matching (numba compile on a fresh checkout)
def test_metric_reconstruction_of_the_temple():
    im1, im2, _, (K, T1), (_, T2) = temple("0008", "0009")
    baseline = float(np.linalg.norm(T1[:3, 3] - T2[:3, 3]))
    rec = reconstruct_images(im1, im2, focal_px=K[0, 0], baseline_m=baseline)
    assert rec.kind == "metric" and len(rec.points) > 50_000
    left, right = (T2, T1) if rec.rectification.swapped else (T1, T2)
    T_rl = np.linalg.solve(right, left)
    assert np.linalg.norm(rec.t) == pytest.approx(baseline)
    cos = (np.trace(T_rl[:3, :3].T @ rec.R) - 1) / 2
    assert np.degrees(np.arccos(min(cos, 1.0))) < 3.0  # principal point is only assumed
    # the temple stands about 0.55 m in front of every camera (its data README)
    assert np.median(rec.points[:, 2]) == pytest.approx(0.55, rel=0.1)


@pytest.mark.slow
def test_metric_reconstruction_matches_the_mock_ground_truth():
    from armstereo.clock import SimClock
    from drivers.mock.camera import MockCamera
    from drivers.mock.scene import default_table_scene

    state = {"T": start_pose()}
    cam = MockCamera(model().mount.intrinsics, lambda: state["T"], clock=SimClock(),
                     scene=default_table_scene(0), noise_sigma=1.0)
    with cam:
        f1 = cam.grab()
        state["T"] = start_pose() @ LATERAL
        f2 = cam.grab()
    rec = reconstruct_images(f1.image, f2.image, focal_px=cam.intrinsics.fx,
                             baseline_m=float(np.linalg.norm(LATERAL[:3, 3])))
    assert not rec.rectification.swapped and rec.kind == "metric"
    uv = rec.K @ (rec.points / rec.points[:, 2:]).T
    u, v = np.rint(uv[:2]).astype(int)
    ok = (u >= 0) & (u < 640) & (v >= 0) & (v < 480)
    truth = f1.depth[v[ok], u[ok]]
    rel = np.abs(rec.points[ok, 2] - truth) / truth
    assert np.nanmedian(rel) < 0.01


def test_projective_without_focal_length_and_option_errors():
    im1, im2, _, _, _ = temple("0008", "0009")
    with pytest.raises(ConfigError, match="focal"):
        reconstruct_images(im1, im2, baseline_m=0.2)
    with pytest.raises(ConfigError, match="> 0"):
        reconstruct_images(im1, im2, focal_px=-3.0)
    with pytest.raises(EpipolarError, match="differ in size"):
        reconstruct_images(im1, im2[:100])
    with pytest.raises(EpipolarError, match="matches"):
        estimate_from_images(im1, np.zeros_like(im2))
