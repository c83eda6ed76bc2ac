"""Mount files written by the calibration read back bit-exactly; truth errors."""

from __future__ import annotations

import math

import numpy as np
import pytest

from armstereo.calibration.mount_file import mount_toml, truth_error
from armstereo.calibration.poses import exp6, rotmat
from armstereo.camera_model import Intrinsics
from armstereo.errors import ConfigError
from armstereo.mount import CameraMount
from armstereo.transforms import make_T

X = make_T(rotmat([0.0123456789, -0.0312, 1.5707]), [0.0013579, -0.07024681, 0.0411111])
INTR = Intrinsics(640, 480, np.array([[612.123456789, 0.0, 322.98765], [0.0, 612.7, 236.1],
                                      [0.0, 0.0, 1.0]]),
                  np.array([-0.0812345, 0.0512, 0.0, 0.0, 0.0]))


def test_written_mount_reads_back_bit_exactly(tmp_path):
    text = mount_toml("my_cam", X, INTR, comments=["calibrated in a test"])
    path = tmp_path / "my_cam.toml"
    path.write_text(text)
    m = CameraMount.load(path)
    assert m.name == "my_cam"
    # CameraMount re-orthonormalises nothing: the matrix and vector round-trip exactly
    np.testing.assert_array_equal(m.T_flange_camera, X)
    np.testing.assert_array_equal(m.intrinsics.K, INTR.K)
    np.testing.assert_array_equal(m.intrinsics.dist, INTR.dist)
    assert text.startswith("# calibrated in a test\n") and "rotation_matrix" in text


def test_bad_names_and_numbers_are_refused():
    with pytest.raises(ConfigError, match="mount name"):
        mount_toml("my cam", X, INTR)
    bad = X.copy()
    bad[0, 3] = math.nan
    with pytest.raises(ConfigError, match="non-finite"):
        mount_toml("cam", bad, INTR)


def test_truth_error_measures_translation_rotation_and_focal():
    true = CameraMount("t", X, INTR)
    off = X @ exp6([0.0, 0.0, math.radians(0.1), 0.001, 0.0, 0.0])
    K = INTR.K.copy()
    K[0, 0] *= 1.01
    K[1, 1] *= 1.01
    est = CameraMount("e", off, Intrinsics(640, 480, K, INTR.dist))
    err = truth_error(est, true)
    assert set(err) == {"translation_m", "rotation_deg", "focal_rel"}
    assert err["translation_m"] == pytest.approx(0.001, rel=1e-9)
    assert err["rotation_deg"] == pytest.approx(0.1, rel=1e-6)
    assert err["focal_rel"] == pytest.approx(0.01, rel=1e-9)
