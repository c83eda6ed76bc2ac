"""Pre-flight refuses pairs that are not stereo; reconstruct tells when the images disagree
with the recorded poses (the epipolar self-check), and stays quiet with --no-check."""

import numpy as np

from armstereo.capture.plan import CaptureSettings, plan_capture
from armstereo.cli.main import main
from armstereo.mount import CameraMount
from armstereo.robot.arm_model import ArmModel
from drivers.mock.start_poses import table_start

WIDE_ANGLE = """[hand_eye]
translation = [0.0, -0.07, 0.04]
[camera]
width = 640
height = 480
K = [[250.0, 0.0, 319.5], [0.0, 250.0, 239.5], [0.0, 0.0, 1.0]]
"""


def test_a_baseline_whose_epipole_lies_in_the_image_is_refused(tmp_path):
    mount = tmp_path / "wide.toml"
    mount.write_text(WIDE_ANGLE)
    model = ArmModel.load("ur5e", mount=CameraMount.load(mount))
    q0 = table_start(model)
    # 35 deg from the optical axis: allowed by the direction rule, but with f = 250 px the
    # epipole lands 175 px from the centre, inside the 640 px wide image
    d = np.array([np.sin(np.radians(35.0)), 0.0, np.cos(np.radians(35.0))])
    plan = plan_capture(model, q0, CaptureSettings(baseline=0.05, direction=d))
    motion = next(c for c in plan.checks if c.name == "stereo motion")
    assert not motion.ok and "epipole lies inside image" in motion.detail
    assert not plan.ok
    sideways = plan_capture(model, q0, CaptureSettings(baseline=0.05,
                                                       direction=np.array([1.0, 0, 0])))
    assert next(c for c in sideways.checks if c.name == "stereo motion").ok


def test_reconstruct_warns_on_a_miscalibrated_pair_unless_told_not_to(tmp_path, capsys):
    rec = tmp_path / "off.mcap"
    # the camera really sits rolled 1 deg from what the mount says (and what is recorded)
    assert main(["-q", "capture", "--baseline", "0.08", "--out", str(rec),
                 "--mock-hand-eye-offset", "0,0,0,0,0,1"]) == 0
    capsys.readouterr()
    assert main(["-q", "reconstruct", str(rec), "--out", str(tmp_path / "a")]) == 0
    err = capsys.readouterr().err
    assert "disagree with the recorded poses" in err and "clockwise" in err
    assert main(["-q", "reconstruct", str(rec), "--out", str(tmp_path / "b"),
                 "--no-check"]) == 0
    assert "disagree" not in capsys.readouterr().err
