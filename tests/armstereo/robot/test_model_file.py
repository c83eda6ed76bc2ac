"""Saved calibrated models (armstereo.robot.model_file): exact round trip, tamper check, and
``--robot`` taking a name, a URDF or a model file."""

from __future__ import annotations

import json

import numpy as np
import pytest

from armstereo.errors import ConfigError
from armstereo.robot.arm_model import ArmModel
from armstereo.robot.dh import fk, nominal_table, ur_calibration_hash
from armstereo.robot.model_file import (
    FORMAT,
    is_model_file,
    load_arm_model,
    load_model_file,
    save_model_file,
)
from armstereo.robot.synthetic import synthetic_calibration
from robot_models import MODELS_DIR


@pytest.fixture
def table():
    return synthetic_calibration("ur5e", 9)


def test_round_trip_is_exact(tmp_path, table):
    path = save_model_file(tmp_path / "arm.json", table, host="192.168.1.10",
                           software_version="5.12.0.1101534")
    doc = json.loads(path.read_text())
    assert doc["format"] == FORMAT and doc["format_version"] == 1
    assert doc["model"] == "ur5e" and doc["sha256"] == table.sha256
    assert doc["ur_calibration_hash"] == ur_calibration_hash(table)
    assert doc["calibration_status"] == 2 and doc["checksums"] == list(table.checksums)
    assert set(doc["dh"]) == {"theta", "a", "d", "alpha"}
    loaded = load_model_file(path)
    assert loaded.table == table  # every float bit for bit
    assert loaded.controller == {"host": "192.168.1.10", "software_version": "5.12.0.1101534"}
    assert loaded.saved_at.endswith("Z")
    assert not list(tmp_path.glob(".arm.json.*"))  # no temporary file left behind


def test_robot_argument_takes_names_urdfs_and_model_files(tmp_path, table):
    path = save_model_file(tmp_path / "arm.json", table)
    arm = load_arm_model(str(path), mount="default_wrist_camera")
    assert arm.dh == table and arm.mount is not None
    q = np.random.default_rng(0).uniform(-3, 3, 6)
    np.testing.assert_allclose(arm.flange_pose(q), fk(table, q), atol=1e-12)
    assert load_arm_model("ur5e").dh is None
    assert load_arm_model(MODELS_DIR / "ur5.urdf").name == "ur5"
    assert is_model_file("x/ARM.JSON") and not is_model_file("ur5e")


def test_edited_table_is_refused(tmp_path, table):
    path = save_model_file(tmp_path / "arm.json", table)
    doc = json.loads(path.read_text())
    doc["dh"]["d"][1] += 1e-6
    path.write_text(json.dumps(doc))
    with pytest.raises(ConfigError, match="sha256"):
        load_model_file(path)


@pytest.mark.parametrize("text, match", [
    ("not json", "cannot read"),
    ('{"format": "something else"}', "not an armstereo robot model"),
    (json.dumps({"format": FORMAT, "format_version": 99}), "version 99"),
    (json.dumps({"format": FORMAT, "format_version": 1, "model": "ur5e"}), "lacks"),
])
def test_bad_files_are_refused(tmp_path, text, match):
    path = tmp_path / "bad.json"
    path.write_text(text)
    with pytest.raises(ConfigError, match=match):
        load_model_file(path)
    with pytest.raises(ConfigError):
        load_arm_model(path)


def test_missing_file_is_a_config_error(tmp_path):
    with pytest.raises(ConfigError, match="cannot read"):
        load_model_file(tmp_path / "none.json")


def test_nominal_table_saves_too(tmp_path):
    table = nominal_table("ur10e")
    loaded = load_model_file(save_model_file(tmp_path / "n.json", table)).table
    assert loaded == table and loaded.is_nominal
    assert ArmModel.from_dh(loaded).name == "ur10e"
