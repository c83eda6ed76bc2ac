"""One simulated cell: a profile and a seed are the same arm, camera and board for every
command, whatever mount file the software is given."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from armstereo import backends
from armstereo.calibration.board import parse_board
from armstereo.errors import ConfigError
from armstereo.kinematics import ArmModel
from armstereo.mount import CameraMount
from armstereo.transforms import make_T
from drivers.mock.board import board_pose, board_primitive, printed_board, sheet_extent
from drivers.mock.cell import cell_camera, cell_name
from drivers.mock.profile import IDEAL, REALISTIC, BoardErrors
from drivers.mock.render import Scene

BOARD = parse_board("chessboard:17x12:0.016")


@pytest.fixture(scope="module")
def bundled() -> CameraMount:
    return CameraMount.load(None)


def camera_truth(mount: CameraMount, profile: str, seed: int, **camera) -> dict:
    """The mock camera's recorded truth when the software believes ``mount``."""
    model = ArmModel.load("ur5e", mount=mount)
    arm = backends.build_arm("mock", backends.arm_config("mock", profile=profile, seed=seed),
                             model)
    with arm:
        cam = backends.build_camera("mock", backends.camera_config(
            "mock", profile=profile, seed=seed, **camera), model, arm)
        return json.loads(cam.recording_metadata()["mock_camera_truth"]), cam


def test_the_realistic_camera_is_the_cells_whatever_the_software_believes(bundled):
    other = dataclasses.replace(bundled, name="calibrated", T_flange_camera=bundled.
                                T_flange_camera @ make_T(np.eye(3), [0.003, 0, 0]))
    a, cam = camera_truth(bundled, "realistic", 2)
    b, _ = camera_truth(other, "realistic", 2)
    calib, _ = camera_truth(bundled, "realistic", 2, board=BOARD)  # calibrate's camera
    for key in ("T_flange_camera", "K", "dist", "vignetting"):
        assert a[key] == b[key] == calib[key]
    assert a["cell"] == "realistic seed 2" == cam.recording_metadata()["mock_cell"]
    assert a != camera_truth(bundled, "realistic", 3)[0]  # another seed, another cell
    assert cam.vignetting is not None and cam.intrinsics is bundled.intrinsics


def test_the_ideal_camera_is_exactly_the_mount_in_use(bundled):
    other = dataclasses.replace(bundled, T_flange_camera=bundled.T_flange_camera
                                @ make_T(np.eye(3), [0.003, 0, 0]))
    truth, cam = camera_truth(other, "ideal", 0)
    np.testing.assert_array_equal(truth["T_flange_camera"], other.T_flange_camera)
    assert truth["vignetting"] is None and cam.vignetting is None


def test_a_mount_for_another_image_size_is_refused(bundled):
    small = dataclasses.replace(bundled, intrinsics=bundled.intrinsics.scaled(320, 240))
    with pytest.raises(ConfigError, match="delivers 640x480 images, the mount file says "
                                          "320x240"):
        cell_camera(REALISTIC, 0, small)
    assert cell_camera(IDEAL, 0, small).mount.intrinsics.size == (320, 240)


def test_the_cells_lens_has_vignetting_about_its_principal_point(bundled):
    cam = cell_camera(REALISTIC, 4, bundled)
    v, intr = cam.vignetting, cam.mount.intrinsics
    assert v.center == (intr.cx, intr.cy)
    assert 0.65 < v.corner_gains().min() < v.corner_gains().max() < 0.85
    assert cell_name(REALISTIC, 4) == "realistic seed 4"


def test_the_arm_keeps_what_its_controllers_calibration_cannot_hold(bundled):
    model = ArmModel.load("ur5e", mount=bundled)
    offsets = {}
    for profile in ("ideal", "realistic"):
        arm = backends.build_arm("mock", backends.arm_config("mock", profile=profile), model)
        with arm:
            _, controller = arm.joints_and_controller_pose()
            true = arm.true_flange_pose()
            offsets[profile] = np.linalg.norm(true[:3, 3] - controller[:3, 3])
    assert offsets["ideal"] < 1e-12
    assert 1e-5 < offsets["realistic"] < 5e-4  # encoder noise plus 50 um per axis


def test_the_board_is_printed_as_the_profile_says():
    errors = BoardErrors(scale_rel=0.003, bow_m=0.001, glare=0.5)
    printed = printed_board(errors, BOARD, seed=1)
    assert printed.scale != 1.0 and not printed.flat and printed.glare == 0.5
    x0, y0, x1, y1 = sheet_extent(BOARD)
    sag = printed.sag_m(printed.scale * (x1 - x0) / 2, printed.scale * (y1 - y0) / 2)
    assert 0 < sag < 0.005
    assert printed_board(None, BOARD).flat and printed_board(None, BOARD).scale == 1.0
    T = board_pose(BOARD, 1)
    sheet = board_primitive(BOARD, T, printed)
    # rays straight down onto the sheet's centre and a corner: the centre stands out by sag
    centre = (T @ np.append(BOARD.center, 1.0))[:3]
    scene = Scene([sheet])
    t, idx = scene.intersect(centre + [0, 0, 0.5], np.array([[0.0, 0.0, -1.0]]))
    assert idx[0] == 0 and 0.5 - t[0] == pytest.approx(sag, abs=1e-9)
    flat = board_primitive(BOARD, T)
    t_flat, _ = Scene([flat]).intersect(centre + [0, 0, 0.5], np.array([[0.0, 0.0, -1.0]]))
    assert t_flat[0] == pytest.approx(0.5, abs=1e-12)
