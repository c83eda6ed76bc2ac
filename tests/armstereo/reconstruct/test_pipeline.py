"""Pair -> reconstruction on a synthetic recording with exact ground truth, and the CLI."""

from __future__ import annotations

import dataclasses
import json
import math

import cv2
import numpy as np
import pytest

from armstereo.camera_model import Intrinsics
from armstereo.cli.main import main
from armstereo.devices import Frame
from armstereo.errors import ConfigError, RecordingError
from armstereo.io.images import depth_from_png16
from armstereo.io.ply import read_ply
from armstereo.mount import CameraMount
from armstereo.reconstruct.outputs import write_outputs
from armstereo.reconstruct.pipeline import reconstruct_pair
from armstereo.reconstruct.rectify import rectified_geometry
from armstereo.reconstruct.stereo_options import BirchfieldOptions, SgbmOptions
from armstereo.reconstruct.window import choose_window as plan_disparity
from armstereo.recording import Recording, RecordingWriter
from armstereo.transforms import invert, make_T, rot_x, rot_z
from drivers.mock.scene import Box, Rectangle, Scene, Texture

MOUNT = CameraMount.load()
INTR = MOUNT.intrinsics
HEIGHT = 0.55  # camera above the table (m), as in the capture's start pose
# The table (z = 0) and a 12 x 8 x 7 cm box on it, from the mock camera's ray caster.
SCENE = Scene([Rectangle(np.eye(4), 0.6, 0.6, Texture((40, 60, 90), (200, 210, 230), seed=1),
                         name="table"),
               Box((0.0, 0.0, 0.035), (0.12, 0.08, 0.07), Texture((90, 30, 30), (240, 180, 170),
                                                                    seed=2), name="box")],
              support="table")


def render(T_base_cam: np.ndarray, intr: Intrinsics = INTR) -> tuple[np.ndarray, np.ndarray]:
    """BGR image and exact z-depth (m) of the table scene."""
    return SCENE.render(T_base_cam, intr)


def camera_pose(offset_cam=(0.0, 0.0, 0.0)) -> np.ndarray:
    """Looking straight down from HEIGHT, displaced by ``offset_cam`` in its own frame."""
    T = make_T(rot_x(math.pi) @ rot_z(0.1), [0.02, 0.01, HEIGHT])
    T[:3, 3] += T[:3, :3] @ np.asarray(offset_cam, dtype=float)
    return T


def write_recording(path, offsets, *, calibration: bool = True, direction: str = "x"):
    """A recording with one view per camera offset and a pair for each consecutive two."""
    with RecordingWriter(path, metadata={"robot": "synthetic"}) as w:
        if calibration:
            w.write_calibration(INTR, 1_000)
        centres = []
        for k, off in enumerate(offsets):
            T = camera_pose(off)
            img, depth = render(T)
            T_base_flange = T @ invert(MOUNT.T_flange_camera)
            w.write_view(k, Frame(img, 2_000 + k * 1_000_000, depth), np.zeros(6),
                         [f"j{i}" for i in range(6)], T_base_flange, MOUNT.T_flange_camera,
                         settle_s=0.1)
            centres.append(T[:3, 3])
            if k:
                b = float(np.linalg.norm(centres[k] - centres[k - 1]))
                w.write_pair(k - 1, k - 1, k, b, b, direction)
    return path


@pytest.fixture(scope="module")
def recording(tmp_path_factory):
    path = tmp_path_factory.mktemp("rec") / "scan.mcap"
    # view 0 -> 1 moves along camera +x; 1 -> 2 moves back past 0 (view 2 becomes left);
    # 2 -> 3 moves along camera +y (vertical baseline: rectified images turn by 90 deg)
    return write_recording(path, [(0, 0, 0), (0.06, 0, 0), (-0.02, 0.0, 0), (-0.02, 0.05, 0)])


@pytest.fixture(scope="module")
def recon(recording):
    return reconstruct_pair(Recording.open(recording)[0])


def test_reconstruction_matches_ground_truth(recon):
    truth = recon.depth_truth
    est = recon.depth_original
    assert truth is not None and est.shape == truth.shape
    ok = np.isfinite(est)
    assert ok.mean() > 0.7
    rel = np.abs(est[ok] / truth[ok] - 1)
    assert np.median(rel) < 0.005
    assert np.mean(rel < 0.02) > 0.9
    # points lie on the table or the box (base frame)
    distance = SCENE.truth().distance(recon.points_base)
    assert np.mean(distance < 0.005) > 0.95
    assert np.sum(np.abs(recon.points_base[:, 2] - 0.07) < 0.002) > 1000  # the box's top
    assert recon.points_base.dtype == np.float32 and recon.colors_bgr.dtype == np.uint8
    assert set(recon.timings_s) >= {"decode", "rectify", "match", "triangulate"}
    assert not recon.swapped and recon.left_view == 0


def test_swapped_pair_still_reconstructs(recording):
    recon = reconstruct_pair(Recording.open(recording)[1], far=0.6)
    assert recon.swapped and recon.left_view == 2 and recon.right_view == 1
    ok = np.isfinite(recon.depth_original)
    rel = np.abs(recon.depth_original[ok] / recon.depth_truth[ok] - 1)
    assert np.median(rel) < 0.005


def test_vertical_pair_reconstructs(recording):
    recon = reconstruct_pair(Recording.open(recording)[2])
    assert abs(abs(recon.rectified.rotation_deg) - 90) < 1e-6
    assert recon.rectified.size == (480, 640)
    ok = np.isfinite(recon.depth_original)
    assert ok.mean() > 0.7
    rel = np.abs(recon.depth_original[ok] / recon.depth_truth[ok] - 1)
    assert np.median(rel) < 0.005


def test_auto_disparity_window_uses_the_table(recording):
    pair = Recording.open(recording)[0]
    left = pair.left
    geom, _ = rectified_geometry(left.intrinsics, left.T_base_camera, pair.right.intrinsics,
                                 pair.right.T_base_camera)
    plan = plan_disparity(geom, left.intrinsics, left.T_base_camera)
    assert plan.far == pytest.approx(1.1 * HEIGHT, rel=1e-6)  # straight down: table depth
    fb = geom.fx * geom.baseline
    assert plan.max_disparity == math.ceil(fb * (1 / (0.5 * HEIGHT) - 1 / plan.far)) + 2
    assert "table" in plan.source
    given = plan_disparity(geom, left.intrinsics, left.T_base_camera, near=0.4, far=1.0)
    assert given.far == 1.0 and given.max_disparity == math.ceil(fb * (1 / 0.4 - 1)) + 2
    fixed = plan_disparity(geom, left.intrinsics, left.T_base_camera, max_disparity=16)
    assert fixed.max_disparity == 16 and fixed.near == pytest.approx(fb / (fb / fixed.far + 16))
    with pytest.raises(ConfigError, match="near"):
        plan_disparity(geom, left.intrinsics, left.T_base_camera, near=1.0, far=0.5)
    with pytest.raises(ConfigError, match="max-disparity"):
        plan_disparity(geom, left.intrinsics, left.T_base_camera, max_disparity=5000)


def test_write_outputs(recon, tmp_path):
    paths = write_outputs(recon, tmp_path / "out", "pair000")
    assert set(paths) == {"ply", "depth", "disparity", "rectified", "depth_error", "mcap"}
    cloud = read_ply(paths["ply"])
    assert np.array_equal(cloud.points, recon.points_base)
    assert np.array_equal(cloud.colors_bgr, recon.colors_bgr)
    assert np.array_equal(recon.colors, recon.colors_bgr[:, ::-1])
    depth = depth_from_png16(cv2.imread(str(paths["depth"]), cv2.IMREAD_UNCHANGED))
    ok = np.isfinite(recon.depth_original)
    assert np.array_equal(np.isfinite(depth), ok)
    assert np.abs(depth[ok] - recon.depth_original[ok]).max() <= 0.0005 + 1e-6
    for kind in ("disparity", "rectified", "depth_error"):
        assert cv2.imread(str(paths[kind])) is not None
    out = Recording.open(paths["mcap"])
    assert len(out) == 1 and len(out.point_clouds) == 1
    assert out.metadata["kind"] == "reconstruction"
    assert set(recon.timings_s) >= {"write", "write_extras"}
    # the recording says how it was matched, every option of it
    record = json.loads(out.metadata["matcher"])
    assert record["method"] == "birchfield" == recon.method
    assert BirchfieldOptions(**record["options"]) == recon.stereo == BirchfieldOptions()


def test_the_matcher_options_object_or_the_old_dict_match_alike(recording):
    pair = Recording.open(recording)[0]
    by_object = reconstruct_pair(pair, stereo=BirchfieldOptions(subpixel="none"))
    by_dict = reconstruct_pair(pair, stereo_options={"subpixel": "none"})
    assert by_object.stereo == by_dict.stereo == BirchfieldOptions(subpixel="none")
    np.testing.assert_array_equal(by_object.disparity, by_dict.disparity)
    sgbm = reconstruct_pair(pair, stereo=SgbmOptions())
    assert sgbm.method == "sgbm" and sgbm.stereo == SgbmOptions()
    with pytest.raises(ConfigError, match="does not take SgbmOptions"):
        reconstruct_pair(pair, method="birchfield", stereo=SgbmOptions())
    with pytest.raises(ConfigError, match="not both"):
        reconstruct_pair(pair, stereo=SgbmOptions(), stereo_options={})


def test_pair_without_calibration_is_refused(tmp_path):
    path = write_recording(tmp_path / "nocal.mcap", [(0, 0, 0), (0.05, 0, 0)],
                           calibration=False)
    with pytest.raises(RecordingError, match="calibration"):
        reconstruct_pair(Recording.open(path).pairs[0])


def test_cli_reconstructs_one_pair(recording, tmp_path, capsys):
    assert main(["reconstruct", str(recording), "--pair", "0", "--out", str(tmp_path),
                 "--max-disparity", "48", "--far", "0.6"]) == 0
    out = capsys.readouterr().out
    assert "pair 0:" in out and "disparity 0..48 px" in out and "pair000.ply" in out
    assert (tmp_path / "pair000.ply").is_file()
    assert Recording.open(tmp_path / "pair000.mcap").metadata["robot"] == "synthetic"


@pytest.mark.parametrize("argv,code,message", [
    (["reconstruct", "missing.mcap"], 2, "argument REC.mcap: no such file"),
    (["reconstruct", "{rec}", "--pair", "7"], 2, "--pair 7 is not in"),
    (["reconstruct", "{rec}", "--pair", "x"], 2, "pair number"),
    (["reconstruct", "{rec}", "--max-disparity", "lots"], 2, "whole number"),
    (["reconstruct", "{rec}", "--near", "0.9", "--far", "0.5"], 2, "--near"),
    (["reconstruct", "{nocal}"], 5, "calibration"),
])
def test_cli_bad_input_gives_one_line_errors(argv, code, message, recording, tmp_path, capsys):
    nocal = tmp_path / "nocal.mcap"
    if "{nocal}" in argv:
        write_recording(nocal, [(0, 0, 0), (0.05, 0, 0)], calibration=False)
    argv = [a.format(rec=recording, nocal=nocal) for a in argv]
    assert main(argv + ["--out", str(tmp_path / "o")]) == code
    err = capsys.readouterr().err.strip()
    assert err.startswith("armstereo reconstruct: error:") and message in err
    assert len(err.splitlines()) == 1


def test_pair_without_poses_is_refused(recording):
    pair = Recording.open(recording)[0]
    broken = dataclasses.replace(pair.left, T_base_flange=np.full((4, 4), np.nan))
    with pytest.raises(RecordingError, match="view 0 has no camera pose"):
        reconstruct_pair(dataclasses.replace(pair, left=broken))


@pytest.mark.parametrize("argv, expected", [
    (["--photo-check", "4"], BirchfieldOptions(photo_check=4.0)),
    ([], BirchfieldOptions()),
    (["--photo-check", "4", "--method", "sgbm"], SgbmOptions()),  # a Birchfield-Tomasi option
])
def test_cli_passes_the_photo_check_to_the_matcher(recording, tmp_path, monkeypatch, argv,
                                                   expected):
    from armstereo.cli import reconstruct_cmd

    seen = []
    real = reconstruct_cmd.reconstruct_pair

    def spy(pair, **kwargs):
        seen.append(kwargs["stereo"])
        return real(pair, **kwargs)

    monkeypatch.setattr(reconstruct_cmd, "reconstruct_pair", spy)
    assert main(["-q", "reconstruct", str(recording), "--pair", "0", "--out", str(tmp_path),
                 "--max-disparity", "48", "--far", "0.6", *argv]) == 0
    assert seen == [expected]
