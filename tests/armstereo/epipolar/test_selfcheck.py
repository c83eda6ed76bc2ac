"""The self-check on mock views: ok with the true mount, miscalibrated with an offset one, and
a fitted correction that points the way the camera really is."""

from __future__ import annotations

import re

import numpy as np
import pytest

from armstereo.epipolar.selfcheck import MISCALIBRATION_THRESHOLD_PX, check_views
from armstereo.transforms import make_T, rot_y

from .mock_views import (
    EXACT,
    FORWARD_5MM,
    LATERAL,
    ROLL_1DEG,
    TILTED,
    YAW_1DEG,
    render_pair,
)


def check(rel, D):
    im1, im2, intr, T1, T2 = render_pair(rel, D)
    return check_views(im1, im2, intr, T1, intr, T2, pair=3)


@pytest.fixture(scope="module")
def results():
    return {name: check(rel, D) for name, (rel, D) in {
        "exact": (LATERAL, EXACT), "roll": (LATERAL, ROLL_1DEG), "yaw": (LATERAL, YAW_1DEG),
        "tilted_exact": (TILTED, EXACT), "tilted_forward": (TILTED, FORWARD_5MM)}.items()}


@pytest.mark.parametrize("name", ["exact", "tilted_exact"])
def test_true_mount_is_ok(results, name):
    c = results[name]
    assert c.verdict == "ok", c.reason
    assert c.median_sampson_px < 0.2  # exact poses: a small fraction of a pixel
    assert c.inliers > 200 and c.pair == 3
    assert c.correction is not None and np.all(np.abs(c.correction.rotation_deg) < 0.3)


def test_one_degree_roll_is_miscalibrated_and_the_correction_rolls_clockwise(results):
    c = results["roll"]
    assert c.verdict == "miscalibrated"
    assert c.median_sampson_px > MISCALIBRATION_THRESHOLD_PX
    assert c.correction.rotation_deg[2] == pytest.approx(1.0, abs=0.1)
    assert any(re.search(r"rolled (0\.9|1\.0)\d deg further clockwise", s)
               for s in c.correction.describe()), c.correction.describe()


def test_one_degree_yaw_is_caught_by_the_correction_not_the_distance(results):
    """A yaw moves matches by tenths of a pixel only (sideways baseline), yet bends depth."""
    c = results["yaw"]
    assert c.median_sampson_px < MISCALIBRATION_THRESHOLD_PX
    assert c.verdict == "miscalibrated", c.reason
    assert c.correction.rotation_deg[1] == pytest.approx(1.0, abs=0.1)
    assert any(re.search(r"looks (0\.9|1\.0)\d deg further right", s)
               for s in c.correction.describe()), c.correction.describe()


def test_five_millimetres_forward_on_a_tilted_pair(results):
    c = results["tilted_forward"]
    assert c.verdict == "miscalibrated"
    assert c.correction.translation_mm[2] == pytest.approx(5.0, abs=1.0)
    assert c.correction.translation_determined[2]
    assert any("further forward" in s for s in c.correction.describe())


def test_a_sideways_pair_cannot_see_a_translation_offset(results):
    """Pure translation: the offset moves the cloud rigidly and the images cannot see it."""
    c = results["exact"]
    assert not c.correction.translation_determined.any()
    assert not c.correction.rotation_determined[0]  # rotation about the baseline (camera x)
    assert "cannot see" in c.correction.describe()[-1]


def test_rotation_only_is_inconclusive():
    im = np.zeros((480, 640, 3), np.uint8)
    from armstereo.camera_model import Intrinsics

    intr = Intrinsics(640, 480, np.array([[600.0, 0, 319.5], [0, 600.0, 239.5], [0, 0, 1]]))
    c = check_views(im, im, intr, np.eye(4), intr, make_T(rot_y(0.1), [0, 0, 0]))
    assert c.verdict == "inconclusive" and c.median_sampson_px is None
    assert c.as_dict()["verdict"] == "inconclusive"


def test_json_keys(results):
    d = results["roll"].as_dict()
    assert {"pair", "median_sampson_px", "verdict"} <= d.keys()
    assert d["correction"]["rotation_deg"][2] == pytest.approx(1.0, abs=0.1)


def test_real_photographs_with_their_published_cameras():
    """Held out from every tuning: temple ring views 22.5 degrees apart on converging rays."""
    from armstereo.camera_model import Intrinsics
    from armstereo.transforms import invert

    from .test_uncalibrated import temple

    im1, im2, _, (K1, T1), (K2, T2) = temple("0008", "0009")
    i1, i2 = Intrinsics(640, 480, K1), Intrinsics(640, 480, K2)
    c = check_views(im1, im2, i1, T1, i2, T2)
    assert c.verdict == "ok" and c.median_sampson_px < 0.3 and c.inliers >= 40
    # "recorded" poses with the camera turned 1 degree left of the truth
    D = make_T(rot_y(np.radians(1.0)), [0, 0, 0])
    c = check_views(im1, im2, i1, T1 @ invert(D), i2, T2 @ invert(D))
    assert c.verdict == "miscalibrated"
    assert c.correction.rotation_deg[1] == pytest.approx(1.0, abs=0.5)
