"""Depth scoring is computed from the ground truth: worse estimates score worse."""

import numpy as np
import pytest

from armstereo.camera_model import Intrinsics
from armstereo.errors import StereoError
from armstereo.evaluation.depth import score_depth, visible_mask
from armstereo.transforms import make_T

INTR = Intrinsics(64, 48, np.array([[50.0, 0, 31.5], [0, 50.0, 23.5], [0, 0, 1]]))


def test_exact_depth_scores_perfectly_and_shifted_depth_scores_worse():
    gt = np.full((48, 64), 0.5, np.float32)
    mask = np.ones_like(gt, bool)
    exact = score_depth(gt.copy(), gt, mask)
    assert exact.median_abs_rel_depth_error == 0 and exact.within_1pct == 1 and exact.density == 1
    shifted = score_depth(gt * 1.02, gt, mask)
    assert shifted.median_abs_rel_depth_error == pytest.approx(0.02, rel=1e-5)
    assert shifted.within_1pct == 0
    holes = gt.copy()
    holes[:, :16] = np.nan
    sparse = score_depth(holes, gt, mask)
    assert sparse.density == pytest.approx(0.75) and sparse.within_1pct == pytest.approx(0.75)


def test_mask_excludes_pixels_and_empty_mask_raises():
    gt = np.full((48, 64), 1.0, np.float32)
    est = gt.copy()
    est[:, 32:] = 2.0
    mask = np.zeros_like(gt, bool)
    mask[:, :32] = True
    assert score_depth(est, gt, mask).median_abs_rel_depth_error == 0
    with pytest.raises(StereoError):
        score_depth(est, gt, np.zeros_like(mask))


def test_visible_mask_marks_occlusion_and_out_of_view():
    # Two cameras looking down z, right camera 0.1 m to the right (+x). Plane at 1 m with a
    # box top at 0.6 m in the middle: part of the plane next to the box is hidden on the right.
    T_l, T_r = np.eye(4), make_T(np.eye(3), [0.1, 0, 0])

    def render(T):
        v, u = np.mgrid[0:48, 0:64].astype(float)
        dx, dy = (u - INTR.cx) / INTR.fx, (v - INTR.cy) / INTR.fy
        z = np.full((48, 64), 1.0)
        xb = T[0, 3] + dx * 0.6  # x of the ray at the box top height
        on_box = (np.abs(xb) < 0.1) & (np.abs(dy * 0.6) < 0.1)
        z[on_box] = 0.6
        return z.astype(np.float32)

    vis = visible_mask(render(T_l), INTR, T_l, render(T_r), INTR, T_r)
    row = vis[24]
    # Plane disparity 5 px: left columns 0..4 project outside the right image.
    assert not row[0:4].any()
    # Plane points with X in (-0.233, -0.167) m (left columns ~20..23) are hidden by the box
    # from the right camera: the left-occluded strip just left of the foreground.
    assert not row[21:23].any()
    # Everything else is seen by both: plane left of the strip, box top, plane right of the box.
    assert row[6:19].all() and row[25:39].all() and row[41:64].all()
