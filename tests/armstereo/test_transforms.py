"""One rigid-transform rule for the whole library: exact poses pass, hand-typed ones snap at
input edges, everything else is refused with the offending name."""

import numpy as np
import pytest

from armstereo.errors import ConfigError, RecordingError
from armstereo.transforms import (
    ROTATION_TOLERANCE,
    SNAP_TOLERANCE,
    as_rigid,
    make_T,
    rot_x,
    rot_z,
)


def test_exact_pose_is_returned_as_a_copy():
    T = make_T(rot_z(0.3) @ rot_x(-1.2), [0.1, 0.2, 0.3])
    out = as_rigid(T, "pose")
    assert np.array_equal(out, T) and out is not T


def test_six_decimal_rotation_snaps_only_where_asked():
    R = np.round(rot_z(0.7) @ rot_x(0.4), 4)  # as a calibration tool prints it
    T = make_T(R, [0, 0, 0.1])
    with pytest.raises(ConfigError, match=r"T_flange_camera is not a rigid transform"):
        as_rigid(T, "T_flange_camera")
    snapped = as_rigid(T, "T_flange_camera", snap=True)
    R2 = snapped[:3, :3]
    assert np.abs(R2.T @ R2 - np.eye(3)).max() < 1e-12
    assert np.abs(R2 - R).max() < 1e-4
    # what snapping accepted passes the strict check everywhere after it
    assert np.array_equal(as_rigid(snapped, "again"), snapped)


@pytest.mark.parametrize("T,what", [
    (np.eye(3), "4x4"),
    (np.diag([1.0, 1.0, 1.0, 2.0]), "last row"),
    (np.diag([1.0, 1.0, -1.0, 1.0]), "reflection"),
    (make_T(np.eye(3) + 2 * SNAP_TOLERANCE, [0, 0, 0]), r"R\^T R - I"),
    (np.full((4, 4), np.nan), "NaN"),
    ("not a matrix", "numbers"),
])
def test_refusals_name_the_transform_and_the_problem(T, what):
    with pytest.raises(RecordingError, match=f"view 3 T_base_flange.*{what}"):
        as_rigid(T, "view 3 T_base_flange", error=RecordingError, snap=True)


def test_tolerances_are_ordered():
    assert 0 < ROTATION_TOLERANCE < SNAP_TOLERANCE <= 1e-3


def test_skew_stack_is_the_cross_product():
    from armstereo.transforms import skew_stack

    rng = np.random.default_rng(3)
    v, w = rng.normal(size=(5, 3)), rng.normal(size=3)
    S = skew_stack(v)
    assert S.shape == (5, 3, 3)
    assert np.allclose(S @ w, np.cross(v, w))
    assert np.allclose(S, -np.transpose(S, (0, 2, 1)))
