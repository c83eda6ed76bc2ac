"""Reconstructing an old recording with a mount file calibrated after the capture."""

from __future__ import annotations

import contextlib
import io
import json

import numpy as np
import pytest

from armstereo import backends
from armstereo.apps.demo import score_reconstruction
from armstereo.calibration.mount_file import mount_toml
from armstereo.capture import CaptureSettings, plan_capture
from armstereo.capture.run import model_metadata
from armstereo.capture.session import capture_to_file
from armstereo.cli.main import main
from armstereo.kinematics import ArmModel
from armstereo.mount import CameraMount
from armstereo.photometric.correct import PhotometricOptions
from armstereo.reconstruct.pipeline import reconstruct_pair
from armstereo.recording import Recording
from armstereo.recording.remount import remounted
from armstereo.robot.source import choose_kinematics


@pytest.fixture(scope="module")
def capture(tmp_path_factory):
    """A desk pair of the realistic cell, captured with the bundled mount file, and the
    cell's true camera written as a mount file (what a perfect calibration would write)."""
    folder = tmp_path_factory.mktemp("remount")
    path = folder / "old.mcap"
    given = ArmModel.load("ur5e", mount=CameraMount.load(None))
    arm_cfg = backends.arm_config("mock", profile="realistic", seed=1)
    cam_cfg = backends.camera_config("mock", profile="realistic", seed=1)
    with backends.build_arm("mock", arm_cfg, given) as arm:
        model = choose_kinematics(given, arm, live=False).model
        plan = plan_capture(model, arm.joint_positions(),
                            CaptureSettings(baseline=0.08, direction=np.array([1.0, 0, 0])))
        with backends.build_camera("mock", cam_cfg, model, arm) as camera:
            capture_to_file(arm, camera, model, plan, path, model_metadata(model),
                            progress=None)
            truth = camera.true_intrinsics, camera.vignetting
    meta = json.loads(Recording.open(path).metadata["mock_camera_truth"])
    text = mount_toml("true_camera", np.array(meta["T_flange_camera"]), truth[0],
                      vignetting=truth[1])
    (folder / "true.toml").write_text(text)
    return path, folder / "true.toml"


def test_a_remounted_pair_has_the_new_camera_and_the_old_images(capture):
    path, mount_file = capture
    pair = Recording.open(path)[0]
    mount = CameraMount.load(mount_file)
    new = remounted(pair, mount)
    np.testing.assert_array_equal(new.left.image, pair.left.image)
    np.testing.assert_array_equal(new.left.T_base_flange, pair.left.T_base_flange)
    np.testing.assert_array_equal(new.right.T_base_camera,
                                  pair.right.T_base_flange @ mount.T_flange_camera)
    assert new.left.intrinsics is mount.intrinsics


def run(*argv: str) -> str:
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        assert main(["-q", *argv]) == 0
    return out.getvalue()


def test_reconstruct_with_a_later_mount_file_is_more_accurate(capture, tmp_path):
    path, mount_file = capture
    scores = {}
    for name, extra in (("recorded", []), ("true", ["--mount", str(mount_file)])):
        text = run("reconstruct", str(path), "--method", "sgbm", "--no-check", "--out",
                   str(tmp_path / name), *extra)
        rec = Recording.open(tmp_path / name / "pair000.mcap")
        photo = json.loads(rec.metadata["photometric"])
        scores[name] = (rec, photo, text)
    _, photo, text = scores["true"]
    assert photo["vignetting"]["applied"] and "vignetting, exposure corrected" in text
    assert scores["true"][0].metadata["mount"] == "true_camera"
    assert not scores["recorded"][1]["vignetting"]["applied"]  # the bundled file has none
    # the depth of the same images, scored against the truth: the later mount file wins
    pair = Recording.open(path)[0]
    mount = CameraMount.load(mount_file)
    errors = {}
    for name, p, model in (("recorded", pair, None),
                           ("true", remounted(pair, mount), mount.vignetting)):
        recon = reconstruct_pair(p, method="sgbm", photometric=PhotometricOptions(model=model))
        errors[name] = score_reconstruction(recon.depth_original, pair,
                                            swapped=recon.swapped).median_abs_rel_depth_error
    assert errors["true"] < errors["recorded"] / 3, errors


def test_photometric_none_corrects_nothing(capture, tmp_path):
    path, mount_file = capture
    run("reconstruct", str(path), "--method", "sgbm", "--no-check", "--photometric", "none",
        "--mount", str(mount_file), "--out", str(tmp_path / "raw"))
    photo = json.loads(Recording.open(tmp_path / "raw" / "pair000.mcap").metadata["photometric"])
    assert not photo["vignetting"]["applied"] and not photo["exposure"]["applied"]
    assert not photo["vignetting"]["requested"] and not photo["exposure"]["requested"]
