"""Backend flags come from the config dataclasses; a flag is honoured or refused, never ignored."""

import argparse

import numpy as np
import pytest

from armstereo import backends
from armstereo.cli.backend_flags import add_backend_flags, backend_choice
from armstereo.errors import ConfigError
from armstereo.mount import CameraMount
from armstereo.robot.arm_model import ArmModel


def parse(*argv: str, defaults=None):
    p = argparse.ArgumentParser()
    add_backend_flags(p, defaults=defaults)
    return p.parse_args(list(argv))


def test_opencv_settings_reach_the_camera():
    args = parse("--camera", "opencv:2", "--exposure", "120", "--gain", "3.5",
                 "--white-balance", "4600", "--resolution", "320x240",
                 "--camera-backend", "v4l2")
    choice = backend_choice(args)
    cfg = choice.camera_config
    assert (cfg.device, cfg.exposure, cfg.gain, cfg.white_balance, cfg.resolution,
            cfg.backend) == ("2", 120.0, 3.5, 4600.0, (320, 240), "v4l2")
    model = ArmModel.load("ur5e", mount=CameraMount.load(None))
    arm = backends.build_arm("mock", choice.arm_config, model)
    cam = backends.build_camera(choice.camera, cfg, model, arm)
    assert (cam.device, cam.exposure, cam.gain, cam.white_balance) == (2, 120.0, 3.5, 4600.0)
    assert cam.intrinsics.size == (320, 240)
    # half the resolution: focal length halves, the principal point moves with pixel corners
    K0 = model.mount.intrinsics.K
    assert cam.intrinsics.fx == pytest.approx(K0[0, 0] / 2)
    assert cam.intrinsics.cx == pytest.approx((K0[0, 2] + 0.5) / 2 - 0.5)


@pytest.mark.parametrize("argv,owner", [
    (["--exposure", "5"], "--camera opencv"),
    (["--host", "10.0.0.2"], "--arm ur"),
    (["--camera-noise", "1", "--camera", "opencv:0"], "--camera mock"),
    (["--joint-noise", "0.001", "--arm", "ur", "--host", "h"], "--arm mock"),
])
def test_a_flag_for_another_backend_is_refused(argv, owner):
    with pytest.raises(ConfigError, match=f"applies to {owner} only"):
        backend_choice(parse(*argv))


def test_faults_need_the_backend_that_injects_them():
    choice = backend_choice(parse("--inject-fault", "camera-timeout@3",
                                  "--inject-fault", "disconnect"))
    assert choice.arm_config.faults == ("camera-timeout@3", "disconnect")
    with pytest.raises(ConfigError, match="camera-timeout needs a mock backend"):
        backend_choice(parse("--camera", "opencv:0", "--inject-fault", "camera-timeout"))
    with pytest.raises(ConfigError, match="unknown fault|not a fault|fault"):
        backend_choice(parse("--inject-fault", "explode"))


def test_command_defaults_show_in_help_and_apply(capsys):
    p = argparse.ArgumentParser()
    add_backend_flags(p, defaults={"noise": 2.0})
    p.print_help()
    assert "sensor noise sigma in grey levels (default 2.0)" in " ".join(
        capsys.readouterr().out.split())
    choice = backend_choice(p.parse_args([]), defaults={"noise": 2.0})
    assert choice.camera_config.noise == 2.0
    choice = backend_choice(p.parse_args(["--camera-noise", "0.5"]), defaults={"noise": 2.0})
    assert choice.camera_config.noise == 0.5


@pytest.mark.parametrize("argv,message", [
    (["--camera-noise", "-1"], "--camera-noise must be >= 0 grey levels"),
    (["--joint-noise", "nan"], "--joint-noise must be a finite number"),
    (["--camera", "opencv:0", "--resolution", "640by480"], "--resolution must be"),
    (["--camera", "opencv:0", "--white-balance", "0"], "--white-balance must be > 0"),
    (["--camera", "webcam"], "unknown camera"),
])
def test_bad_values_are_named(argv, message):
    with pytest.raises(ConfigError, match=message):
        backend_choice(parse(*argv))


def test_registry_builds_each_backend_from_its_config():
    model = ArmModel.load("ur5e", mount=CameraMount.load(None))
    arm = backends.build_arm("mock", backends.arm_config("mock", layout="horizontal"), model)
    with arm:
        q = arm.joint_positions()
    assert np.allclose(q, backends.mock_start_joints(model, "horizontal"))
    ur = backends.build_arm("ur", backends.arm_config("ur", host="10.1.2.3"), model)
    assert ur.host == "10.1.2.3" and not ur.is_connected
    with pytest.raises(ConfigError, match="needs a URArmConfig"):
        backends.build_arm("ur", backends.arm_config("mock"), model)
    with pytest.raises(ConfigError, match="has no option exposure"):
        backends.camera_config("mock", exposure=3.0)
