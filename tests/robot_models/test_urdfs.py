"""The generated UR URDFs: up to date, loadable by Pinocchio, right joints, limits and frames."""

import subprocess
import sys
import xml.etree.ElementTree as ET

import numpy as np
import pinocchio as pin
import pytest

from armstereo.robot.arm_model import JOINT_NAMES, MODEL_NAMES
from robot_models import MODELS_DIR, generate_urdfs

TWO_PI = 2 * np.pi
# Joint speed limits in deg/s, base to wrist 3 (UR manuals via the ROS descriptions).
SPEED_DEG_S = {
    "ur3e": (180, 180, 180, 360, 360, 360),
    "ur5e": (180,) * 6,
    "ur10e": (120, 120, 180, 180, 180, 180),
    "ur16e": (120, 120, 180, 180, 180, 180),
    "ur5": (180,) * 6,
}


def test_generator_check_passes_on_committed_files():
    script = MODELS_DIR / "generate_urdfs.py"
    done = subprocess.run([sys.executable, str(script), "--check"], capture_output=True,
                          text=True, timeout=60)
    assert done.returncode == 0, done.stderr
    assert "up to date" in done.stdout


def test_generator_check_names_a_stale_file(tmp_path, capsys):
    assert generate_urdfs.main(["--out-dir", str(tmp_path)]) == 0
    assert generate_urdfs.main(["--check", "--out-dir", str(tmp_path)]) == 0
    path = tmp_path / "ur10e.urdf"
    path.write_text(path.read_text().replace("-0.6127", "-0.6128"))
    (tmp_path / "ur3e.urdf").unlink()
    assert generate_urdfs.main(["--check", "--out-dir", str(tmp_path)]) == 1
    err = capsys.readouterr().err
    assert "ur10e.urdf" in err and "ur3e.urdf" in err and "ur5e.urdf" not in err


def test_generator_output_is_deterministic():
    for spec in generate_urdfs.SPECS:
        assert generate_urdfs.render_urdf(spec) == generate_urdfs.render_urdf(spec)
    assert sorted(s.name for s in generate_urdfs.SPECS) == sorted(MODEL_NAMES)


@pytest.mark.parametrize("name", MODEL_NAMES)
def test_urdf_loads_in_pinocchio_with_ur_joints_and_limits(name):
    model = pin.buildModelFromUrdf(str(MODELS_DIR / f"{name}.urdf"))
    assert model.nq == model.nv == 6
    assert tuple(model.names[1:]) == JOINT_NAMES
    expected = np.array([TWO_PI, TWO_PI, np.pi, TWO_PI, TWO_PI, TWO_PI])
    assert np.array_equal(model.upperPositionLimit, expected)
    assert np.array_equal(model.lowerPositionLimit, -expected)
    assert np.allclose(model.velocityLimit, np.radians(SPEED_DEG_S[name]), rtol=0, atol=1e-15)
    assert np.all(model.effortLimit > 0)
    for frame in ("base_link", "base", "tool0"):
        assert model.existFrame(frame)
    assert not model.existFrame("flange")


@pytest.mark.parametrize("name", MODEL_NAMES)
def test_base_is_base_link_turned_half_a_turn_about_z(name):
    model = pin.buildModelFromUrdf(str(MODELS_DIR / f"{name}.urdf"))
    data = model.createData()
    rng = np.random.default_rng(7)
    pin.framesForwardKinematics(model, data, rng.uniform(-3, 3, 6))
    T_base_link_base = data.oMf[model.getFrameId("base")].homogeneous
    assert np.allclose(T_base_link_base, np.diag([-1.0, -1.0, 1.0, 1.0]), atol=1e-15)


@pytest.mark.parametrize("name", MODEL_NAMES)
def test_urdf_is_kinematic_only_and_names_its_dh_source(name):
    text = (MODELS_DIR / f"{name}.urdf").read_text()
    root = ET.fromstring(text.split("?>", 1)[1])
    assert root.get("name") == name
    assert not root.findall(".//mesh") and not root.findall(".//visual")
    assert "DH Parameters for calculations of kinematics and dynamics" in text
    assert "do not edit by hand" in text
    spec = next(s for s in generate_urdfs.SPECS if s.name == name)
    for value in (spec.d1, spec.a2, spec.a3, spec.d4, spec.d5, spec.d6):
        assert repr(value) in text
