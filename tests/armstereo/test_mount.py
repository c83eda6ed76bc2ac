"""Mount files: the optional [vignetting] section, and older files without it."""

from __future__ import annotations

import pytest

from armstereo.errors import ConfigError
from armstereo.mount import CameraMount
from armstereo.photometric.vignetting import Vignetting

# A mount file as armstereo wrote them before the photometric calibration existed.
OLD_FILE = """# Calibrated by armstereo from 15 views of chessboard:17x12:0.016.
name = "old_camera"

[hand_eye]
translation = [0.00243, -0.07183, 0.04316]
rotation_matrix = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]

[camera]
width = 640
height = 480
K = [[614.2, 0.0, 321.7], [0.0, 614.3, 245.0], [0.0, 0.0, 1.0]]
dist = [-0.0721, 0.0442, 0.0, 0.0, 0.0]
"""


def test_an_older_mount_file_loads_without_vignetting(tmp_path):
    path = tmp_path / "old.toml"
    path.write_text(OLD_FILE)
    mount = CameraMount.load(path)
    assert mount.name == "old_camera" and mount.vignetting is None
    assert mount.intrinsics.fx == 614.2 and mount.source == OLD_FILE
    assert CameraMount.load(None).vignetting is None  # the bundled file is such a file too


def test_the_vignetting_section_loads(tmp_path):
    model = Vignetting(640, 480, (321.7, 245.0), (-0.17, -0.08, 0.0))
    path = tmp_path / "new.toml"
    path.write_text(OLD_FILE + "\n" + "\n".join(model.toml_lines()))
    assert CameraMount.load(path).vignetting == model


def test_a_bad_vignetting_section_is_one_line_naming_the_file(tmp_path):
    path = tmp_path / "bad.toml"
    path.write_text(OLD_FILE + "\n[vignetting]\nk = [-3.0]\n")
    with pytest.raises(ConfigError, match=r"bad.toml: \[vignetting\]: .*fall-off"):
        CameraMount.load(path)
