"""Capture on the mock backends: planning, pre-flight refusals, end to end, and faults."""

from __future__ import annotations

import numpy as np
import pytest

from armstereo.capture import CaptureSettings, plan_capture
from armstereo.capture.plan import parse_direction
from armstereo.capture.session import confirm_live_motion
from armstereo.cli.capture_cmd import ask_to_move
from armstereo.cli.main import main
from armstereo.errors import ConfigError, PreflightError, UserAbort
from armstereo.recording import Recording
from armstereo.robot.arm_model import ArmModel
from drivers.mock.start_poses import table_start as mock_start_configuration


@pytest.fixture(scope="module")
def model() -> ArmModel:
    return ArmModel.load("ur5e", mount="default_wrist_camera")


def settings(baseline=0.1, direction="x", pairs=2, **kw) -> CaptureSettings:
    d, label = parse_direction(direction)
    return CaptureSettings(baseline=baseline, direction=d, direction_label=label, pairs=pairs,
                           **kw)


def test_plan_moves_camera_along_its_own_axis(model):
    q0 = mock_start_configuration(model)
    plan = plan_capture(model, q0, settings(direction="-y"))
    assert plan.ok, plan.describe()
    R = model.camera_pose(q0)[:3, :3]
    steps = np.diff(np.array(plan.camera_positions), axis=0)
    for s in steps:
        assert np.allclose(s, R @ np.array([0, -0.1, 0]), atol=1e-12)
    for q, T in zip(plan.q_views, plan.T_base_flange, strict=True):
        assert np.allclose(model.flange_pose(q), T, atol=1e-7)


def test_preflight_refuses_unreachable_and_forward_baselines(model):
    q0 = mock_start_configuration(model)
    far = plan_capture(model, q0, settings(baseline=0.5, pairs=4))
    assert not far.ok
    with pytest.raises(PreflightError, match="nothing moved"):
        far.require_ok()
    forward = plan_capture(model, q0, settings(direction="z"))
    assert [c.name for c in forward.checks if not c.ok] == ["baseline direction", "stereo motion"]
    with pytest.raises(ConfigError):
        plan_capture(model, q0, settings(baseline=-0.1))
    with pytest.raises(ConfigError):
        parse_direction("sideways")


def test_preflight_refuses_a_path_leaving_the_workspace(model):
    from armstereo.capture import Workspace

    q0 = mock_start_configuration(model)
    cam = model.camera_pose(q0)[:3, 3]
    box = Workspace((cam[0] - 0.05, cam[1] - 0.05, 0.0), (cam[0] + 0.05, cam[1] + 0.05, 1.0))
    plan = plan_capture(model, q0, settings(workspace=box))
    failed = [c for c in plan.checks if not c.ok]
    assert [c.name for c in failed] == ["workspace"]
    assert "leaves" in failed[0].detail


def test_capture_end_to_end_achieves_the_baseline(tmp_path, capsys):
    out = tmp_path / "x.mcap"
    code = main(["capture", "--arm", "mock", "--camera", "mock", "--robot", "ur5e",
                 "--baseline", "0.1", "--pairs", "2", "--out", str(out), "--yes"])
    assert code == 0, capsys.readouterr().err
    rec = Recording.open(out)
    assert len(rec) == 2
    for pair in rec:
        assert pair.commanded_baseline_m == 0.1
        assert abs(pair.achieved_baseline_m - 0.1) < 0.0005
        c_l, c_r = pair.left.T_base_camera[:3, 3], pair.right.T_base_camera[:3, 3]
        assert abs(np.linalg.norm(c_r - c_l) - 0.1) < 0.0005
        assert pair.left.image.shape == (480, 640, 3) and pair.left.depth is not None
    assert "achieved" in capsys.readouterr().out


def test_dry_run_prints_the_plan_and_writes_nothing(tmp_path, capsys):
    out = tmp_path / "x.mcap"
    assert main(["capture", "--baseline", "0.1", "--pairs", "2", "--out", str(out),
                 "--dry-run"]) == 0
    text = capsys.readouterr().out
    assert "view 2" in text and "[ok] singularity" in text and "nothing moved" in text
    assert not out.exists()


def test_unsafe_plan_exits_with_one_line_and_moves_nothing(tmp_path, capsys):
    out = tmp_path / "x.mcap"
    assert main(["capture", "--baseline", "0.5", "--pairs", "4", "--out", str(out)]) == 3
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "pre-flight check" in err[0]
    assert not out.exists()


@pytest.mark.parametrize(("fault", "code", "views", "words"), [
    ("disconnect@2", 4, 2, "connection"),
    ("protective-stop@1", 4, 1, "protective"),
    ("camera-timeout@2", 4, 1, "timeout"),
])
def test_faults_keep_what_was_recorded(tmp_path, capsys, fault, code, views, words):
    out = tmp_path / "x.mcap"
    argv = ["-q", "capture", "--pairs", "2", "--out", str(out), "--inject-fault", fault]
    assert main(argv) == code
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and words in err[0].lower() and f"{views} view(s) kept" in err[0]
    rec = Recording.open(out)
    assert len(rec.views) == views


def test_existing_output_is_not_overwritten(tmp_path, capsys):
    out = tmp_path / "x.mcap"
    out.write_bytes(b"precious")
    assert main(["capture", "--out", str(out)]) == 2
    assert out.read_bytes() == b"precious"
    assert "--force" in capsys.readouterr().err


def test_live_motion_needs_yes_or_a_typed_confirmation(monkeypatch):
    def confirm(yes=False):
        confirm_live_motion(live=True, yes=yes, ask=lambda: ask_to_move("The ur5e "))

    monkeypatch.setattr("sys.stdin.isatty", lambda: False)
    with pytest.raises(UserAbort, match="--yes"):
        confirm()
    monkeypatch.setattr("sys.stdin.isatty", lambda: True)
    monkeypatch.setattr("builtins.input", lambda prompt: "no")
    with pytest.raises(UserAbort, match="nothing moved"):
        confirm()
    monkeypatch.setattr("builtins.input", lambda prompt: "move")
    confirm()
    monkeypatch.setattr("builtins.input", lambda prompt: pytest.fail("asked despite --yes"))
    confirm(yes=True)
    confirm_live_motion(live=False, yes=False, ask=lambda: pytest.fail("asked for the mock"))
