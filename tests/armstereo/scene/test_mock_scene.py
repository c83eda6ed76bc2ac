"""The issue's gate on the real chain: the mock table scene, one pair, analysed.

The demo (mock UR5e, mock camera, Birchfield-Tomasi) makes the cloud; the analysis is scored
against the scene's exact primitives. One object cannot meet every gate from one pair, and
the tests say so instead of loosening the gates; one more meets them only with a check the
demo turns on for clean views:

- part of the can's top lies outside one camera's image, so stereo cannot see it (checked
  below by projecting the true rim into both views); its footprint and centre describe the
  visible part, the analysis flags it ``partial`` and the gates apply to the objects in view;
- the crate (10 cm tall) needs the demo's photo-consistency check (on for the ideal
  profile, :meth:`DemoOptions.matcher_options`): without it the matcher carries the crate's
  top across its steep side and the half-occluded table beside it (foreground fattening along
  the baseline), 11-13 mm too wide with the centre 2.4-4.4 mm off (seeds 0-5), and those
  points sit at the top's height, so no cloud-only filter can tell them from the top. With
  it: within 3.7 mm, centre within 1.8 mm (bench/results/footprint.md).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from armstereo.apps.demo import DemoOptions, run_demo
from armstereo.evaluation.scene_score import score_scene
from armstereo.recording import Recording
from armstereo.scene import analyze_scene, load_cloud
from drivers.mock.scene import default_table_scene

pytestmark = pytest.mark.slow  # ~5 s warm; the first run compiles the matcher (~30 s)

CENTRE_M, HEIGHT_M, FOOTPRINT_M = 0.003, 0.002, 0.005
TILT_DEG, PLANE_HEIGHT_M = 0.5, 0.001


@pytest.fixture(scope="module")
def demo(tmp_path_factory):
    out = tmp_path_factory.mktemp("demo")
    run_demo(out, DemoOptions(profile="ideal"))  # the gates are about the exact mock
    truth = default_table_scene(DemoOptions().seed).truth()
    analysis = analyze_scene(load_cloud(out / "points.ply"))
    return out, truth, analysis, score_scene(analysis, truth)


def test_every_object_found_none_invented_and_the_plane(demo):
    _, truth, _, score = demo
    assert score.missed == () and score.phantoms == ()
    assert len(score.matched) == len(truth.objects()) == 7
    assert score.plane_tilt_deg < TILT_DEG
    assert abs(score.plane_height_error_m) < PLANE_HEIGHT_M


def test_objects_in_view_meet_the_centre_height_and_footprint_gates(demo):
    _, _, _, score = demo
    checked = [m for m in score.matched if not m.partial]
    assert {m.name for m in checked} == {"crate", "book", "puck", "ball", "block", "marble"}
    for m in checked:
        assert abs(m.height_error_m) < HEIGHT_M, m
        assert m.center_error_m < CENTRE_M, m
        assert abs(m.length_error_m) < FOOTPRINT_M, m
        assert abs(m.width_error_m) < FOOTPRINT_M, m


def test_the_partial_object_is_the_one_the_camera_cuts(demo):
    out, truth, _, score = demo
    partial = {m.name for m in score.matched if m.partial}
    assert partial == {"can"}
    can = next(p for p in truth.primitives if p.name == "can")
    r, h = can.dims
    rim = [can.T_base_local[:3, 3] + (r * math.cos(a), r * math.sin(a), h)
           for a in np.linspace(0, 2 * math.pi, 72, endpoint=False)]
    pair = Recording.open(out / "demo.mcap")[0]
    outside = []
    for view in (pair.left, pair.right):
        cam = np.linalg.inv(view.T_base_camera)
        p = (np.asarray(rim) @ cam[:3, :3].T + cam[:3, 3]) @ view.intrinsics.K.T
        u, v = p[:, 0] / p[:, 2], p[:, 1] / p[:, 2]
        w, hgt = view.intrinsics.size
        outside.append(np.mean((u < 0) | (u > w - 1) | (v < 0) | (v > hgt - 1)))
    assert max(outside) > 0.2  # a good part of the rim is out of one of the two images
    can_score = next(m for m in score.matched if m.name == "can")
    assert abs(can_score.height_error_m) < HEIGHT_M  # its top is still measured right


def test_tall_box_footprint_on_one_pair(demo):
    """The crate, the one object the matcher fattened (see module doc)."""
    _, _, _, score = demo
    crate = next(m for m in score.matched if m.name == "crate")
    assert crate.center_error_m < CENTRE_M
    assert abs(crate.length_error_m) < FOOTPRINT_M and abs(crate.width_error_m) < FOOTPRINT_M
