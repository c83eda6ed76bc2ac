"""``armstereo capture``'s guards before motion: a dry run moves nothing and writes nothing; live
motion (any arm but the mock) waits for --yes or the typed word, and nothing moves, no camera
opens and no file is written until then. The arm and camera are mock devices standing in for
whatever the command asked for, with every call they get logged."""

from __future__ import annotations

import numpy as np
import pytest

from armstereo.cli import capture_cmd
from armstereo.cli.main import main
from armstereo.robot.arm_model import ArmModel
from drivers.mock.arm import MockArm
from drivers.mock.start_poses import table_start

MOVES = ("move_linear", "move_joints")
HOST = "192.0.2.10"  # TEST-NET-1: never a real controller


class Devices:
    """Stands in for the backend registry: mock devices, whatever backend was named."""

    def __init__(self, monkeypatch):
        self.arm: MockArm | None = None
        self.cameras = 0
        real_camera = capture_cmd.backends.build_camera

        def build_arm(name, config, model: ArmModel):
            self.arm = MockArm(model, table_start(model))
            return self.arm

        def build_camera(spec, config, model, arm):
            self.cameras += 1
            return real_camera("mock", capture_cmd.backends.camera_config("mock"), model, arm)

        monkeypatch.setattr(capture_cmd.backends, "build_arm", build_arm)
        monkeypatch.setattr(capture_cmd.backends, "build_camera", build_camera)

    def calls(self) -> list[str]:
        return [] if self.arm is None else [name for name, _ in self.arm.history]

    def moved(self) -> bool:
        return any(name in MOVES for name in self.calls())


@pytest.fixture
def devices(monkeypatch) -> Devices:
    return Devices(monkeypatch)


def capture(out, *extra) -> list[str]:
    return ["capture", "--baseline", "0.05", "--pairs", "1", "--out", str(out), *extra]


@pytest.mark.parametrize("arm", [["--arm", "mock"], ["--arm", "ur", "--host", HOST]])
def test_a_dry_run_moves_nothing_and_writes_nothing(tmp_path, capsys, devices, arm):
    out = tmp_path / "rec.mcap"
    assert main(capture(out, "--dry-run", *arm)) == 0
    assert not devices.moved() and devices.cameras == 0
    assert not out.exists()
    assert "dry run: nothing moved" in capsys.readouterr().out


def test_a_dry_run_leaves_an_existing_output_alone(tmp_path, devices):
    out = tmp_path / "rec.mcap"
    out.write_bytes(b"an earlier capture")
    assert main(capture(out, "--dry-run")) == 0
    assert out.read_bytes() == b"an earlier capture" and not devices.moved()


def test_a_dry_run_of_an_unsafe_plan_fails_and_moves_nothing(tmp_path, capsys, devices):
    out = tmp_path / "rec.mcap"
    assert main(["capture", "--baseline", "0.5", "--pairs", "4", "--out", str(out),
                 "--dry-run"]) == 3
    assert not devices.moved() and not out.exists()
    assert "[FAIL]" in capsys.readouterr().out


@pytest.mark.parametrize(("tty", "answer"), [(False, None), (True, "no"), (True, ""),
                                             (True, "yes")])
def test_live_motion_without_confirmation_moves_nothing(tmp_path, monkeypatch, capsys, devices,
                                                        tty, answer):
    monkeypatch.setattr("sys.stdin.isatty", lambda: tty)
    monkeypatch.setattr("builtins.input", lambda prompt: answer)
    out = tmp_path / "rec.mcap"
    assert main(capture(out, "--arm", "ur", "--host", HOST)) == 130
    assert not devices.moved() and devices.cameras == 0 and not out.exists()
    assert "nothing moved" in capsys.readouterr().err


@pytest.mark.parametrize("how", ["typed", "--yes"])
def test_live_motion_runs_once_confirmed(tmp_path, monkeypatch, devices, how):
    asked = []
    monkeypatch.setattr("sys.stdin.isatty", lambda: True)
    monkeypatch.setattr("builtins.input", lambda prompt: asked.append(prompt) or " Move ")
    out = tmp_path / "rec.mcap"
    extra = ["--yes"] if how == "--yes" else []
    assert main(capture(out, "--arm", "ur", "--host", HOST, *extra)) == 0
    assert devices.moved() and out.exists()
    assert len(asked) == (how == "typed")


def test_the_confirmation_comes_before_the_first_move(tmp_path, monkeypatch, devices):
    seen = []
    monkeypatch.setattr("sys.stdin.isatty", lambda: True)
    monkeypatch.setattr("builtins.input",
                        lambda prompt: seen.append(list(devices.calls())) or "move")
    assert main(capture(tmp_path / "rec.mcap", "--arm", "ur", "--host", HOST)) == 0
    assert seen and not any(name in MOVES for name in seen[0])


def test_the_mock_arm_needs_no_confirmation(tmp_path, monkeypatch, devices):
    monkeypatch.setattr("sys.stdin.isatty", lambda: True)
    monkeypatch.setattr("builtins.input", lambda prompt: pytest.fail("asked for the mock"))
    assert main(capture(tmp_path / "rec.mcap")) == 0
    assert devices.moved()


def test_the_speed_flags_are_the_plan_and_move_limits(tmp_path, devices):
    assert main(capture(tmp_path / "rec.mcap", "--speed", "0.02", "--acceleration", "0.1")) == 0
    moves = [args for name, args in devices.arm.history if name == "move_linear"]
    assert moves and all(a["speed"] == 0.02 and a["acceleration"] == 0.1 for a in moves)


@pytest.mark.parametrize("flag", [["--speed", "0.3"], ["--speed", "0"], ["--speed", "-0.01"],
                                  ["--acceleration", "1.5"], ["--acceleration", "0"]])
def test_speeds_over_the_caps_are_refused_before_anything_moves(tmp_path, capsys, devices,
                                                                 flag):
    """Refused while parsing (exit 2, naming the flag), before any device is touched."""
    out = tmp_path / "rec.mcap"
    assert main(capture(out, *flag, "--yes")) == 2
    assert not devices.moved() and not out.exists()
    assert f"argument {flag[0]}" in capsys.readouterr().err


def test_faster_moves_than_the_caps_are_refused_by_the_mock_arm_too():
    from armstereo.devices import MAX_LINEAR_ACCELERATION, MAX_LINEAR_SPEED
    from armstereo.errors import ConfigError

    model = ArmModel.load("ur5e", mount="default_wrist_camera")
    arm = MockArm(model, table_start(model))
    arm.connect()
    T = model.flange_pose(arm.joint_positions())
    T[:3, 3] += [0.01, 0, 0]
    for speed, acc in ((MAX_LINEAR_SPEED * 1.01, 0.1), (0.05, MAX_LINEAR_ACCELERATION * 1.01),
                       (0.0, 0.1), (0.05, -1.0)):
        q = arm.joint_positions()
        with pytest.raises(ConfigError):
            arm.move_linear(T, speed, acc)
        assert np.array_equal(arm.joint_positions(), q)
    arm.move_linear(T, MAX_LINEAR_SPEED, MAX_LINEAR_ACCELERATION)  # the caps themselves are fine
