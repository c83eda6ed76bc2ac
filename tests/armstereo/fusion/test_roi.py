"""The region of interest found from the views, and the check that a given one is in view."""

import numpy as np
import pytest

from armstereo.errors import ConfigError
from armstereo.fusion.roi import auto_roi, check_roi_seen, frame_points, in_image
from armstereo.fusion.tsdf import Roi
from tests.armstereo.fusion.synthetic import TARGET, ring_frames


@pytest.fixture(scope="module")
def ring():
    return ring_frames(6)


def test_auto_roi_holds_the_objects_around_the_target(ring):
    frames, truth = ring
    roi = auto_roi(frames, [frame_points(f) for f in frames], margin=0.01)
    objects = truth.objects()
    centres = np.array([o.center_m for o in objects])
    assert roi.contains(centres).all()
    assert roi.lo[2] < 0 < max(o.height_m for o in objects) < roi.hi[2]
    assert roi.contains(TARGET[None]).all()
    # the table reaches 0.6 m from the centre; the box stays where most views look
    size = np.subtract(roi.hi, roi.lo)
    assert size[0] < 0.7 and size[1] < 0.7


def test_points_seen_by_one_view_do_not_stretch_the_box(ring):
    frames, _ = ring
    pts = [frame_points(f) for f in frames]
    base = auto_roi(frames, pts, margin=0.01)
    # a cluster just in front of camera 0, which no other camera frames (a smear, a reflection)
    T = frames[0].T_base_camera
    rng = np.random.default_rng(0)
    cam = np.column_stack([rng.uniform(-0.02, 0.02, 5000), rng.uniform(-0.02, 0.02, 5000),
                           np.full(5000, 0.1)])
    stray = cam @ T[:3, :3].T + T[:3, 3]
    only0 = in_image(frames[0], stray) & ~np.any([in_image(f, stray) for f in frames[1:]], 0)
    stray = stray[only0]
    assert len(stray) > 1000 and not base.contains(stray).any()
    with_stray = auto_roi(frames, [np.vstack([pts[0], stray]), *pts[1:]], margin=0.01)
    # (the subsampling stride changes with the extra points: millimetres, not the 0.3 m the
    # cluster would add)
    np.testing.assert_allclose(with_stray.lo, base.lo, atol=5e-3)
    np.testing.assert_allclose(with_stray.hi, base.hi, atol=5e-3)


def test_no_points_is_a_config_error(ring):
    with pytest.raises(ConfigError, match="no pair produced"):
        auto_roi(ring[0], [np.zeros((0, 3))], margin=0.01)


def test_check_roi_seen(ring):
    frames, _ = ring
    check_roi_seen(Roi(tuple(TARGET - 0.01), tuple(TARGET + 0.01)), frames)
    with pytest.raises(ConfigError, match="outside every view of the 6 pair"):
        check_roi_seen(Roi((5.0, 5.0, 5.0), (5.1, 5.1, 5.1)), frames)


def test_in_image_uses_pixel_centre_bounds(ring):
    f = ring[0][0]
    K = f.K
    h, w = f.depth.shape
    z = 0.5

    def at(u, v):  # base-frame point seen at pixel (u, v), depth z
        cam = np.array([(u - K[0, 2]) / K[0, 0] * z, (v - K[1, 2]) / K[1, 1] * z, z])
        return (f.T_base_camera[:3, :3] @ cam + f.T_base_camera[:3, 3])[None]

    assert in_image(f, at(-0.49, 0))[0] and not in_image(f, at(-0.51, 0))[0]
    assert in_image(f, at(w - 0.51, h - 0.51))[0] and not in_image(f, at(w - 0.49, 0))[0]
