"""A capture into a recording (``capture_to_file``) on the mock arm and a small mock camera:
pairs in the file name their views in order (left = the earlier view, right = the later one,
moved by the baseline along the commanded direction), and Ctrl-C, SIGTERM and writer errors
end with the arm told to stop and the file finished with what was kept."""

from __future__ import annotations

import os
import signal
import threading
from functools import cache

import numpy as np
import pytest

from armstereo.camera_model import Intrinsics
from armstereo.capture import CaptureSettings, plan_capture
from armstereo.capture.plan import parse_direction
from armstereo.capture.session import capture_to_file, sigterm_as_interrupt
from armstereo.errors import CameraTimeout, RecordingError, UserAbort
from armstereo.recording import Recording, RecordingWriter
from armstereo.robot.arm_model import ArmModel
from drivers.mock.arm import MockArm
from drivers.mock.camera import MockCamera
from drivers.mock.start_poses import table_start


@cache
def model() -> ArmModel:
    return ArmModel.load("ur5e", mount="default_wrist_camera")


def rig():
    """A connected mock arm and an 80x60 mock camera (fast to render) on its clock."""
    m = model()
    arm = MockArm(m, table_start(m))
    full = m.mount.intrinsics
    small = Intrinsics(80, 60, full.K * np.array([[0.125], [0.125], [1.0]]))
    camera = MockCamera(small, lambda: m.camera_pose(arm.joint_positions()), clock=arm.clock,
                        supersample=1)
    arm.connect()
    camera.connect()
    return arm, camera


def plan_for(pairs: int, baseline: float = 0.04, direction: str = "x"):
    d, label = parse_direction(direction)
    s = CaptureSettings(baseline=baseline, direction=d, direction_label=label, pairs=pairs,
                        settle_s=0.1)
    plan = plan_capture(model(), table_start(model()), s)
    assert plan.ok
    return plan


def stops(arm: MockArm) -> int:
    return sum(1 for name, _ in arm.history if name == "stop")


@pytest.mark.parametrize("direction", ["x", "-y", "1,-1,0"])
def test_recorded_pairs_name_their_views_in_order(tmp_path, direction):
    arm, camera = rig()
    plan = plan_for(3, direction=direction)
    out = tmp_path / "rec.mcap"
    capture_to_file(arm, camera, model(), plan, out, {}, progress=None)
    rec = Recording.open(out)
    assert [(p.index, p.left.index, p.right.index) for p in rec] == [(0, 0, 1), (1, 1, 2),
                                                                     (2, 2, 3)]
    for pair in rec:
        assert pair.left.timestamp_ns < pair.right.timestamp_ns
        R_left = pair.left.T_base_camera[:3, :3]
        moved = pair.right.T_base_camera[:3, 3] - pair.left.T_base_camera[:3, 3]
        np.testing.assert_allclose(R_left.T @ moved, plan.settings.baseline
                                   * plan.settings.direction, atol=1e-6)


def interrupt_at(view: int, how):
    """A progress callback that interrupts the capture on its way to ``view``."""
    def progress(text: str) -> None:
        if text == f"moving to view {view}":
            how()
    return progress


def ctrl_c():
    raise KeyboardInterrupt


def sigterm():
    os.kill(os.getpid(), signal.SIGTERM)


class Unhandled(Exception):
    """SIGTERM reached the test's own handler: the capture did not handle it."""


@pytest.fixture
def own_sigterm():
    """The test's own SIGTERM handler (whatever the process started with), so a capture that
    fails to handle SIGTERM fails the test instead of ending pytest."""
    def unhandled(signum, frame):
        raise Unhandled("SIGTERM was not handled by the capture")

    previous = signal.signal(signal.SIGTERM, unhandled)
    yield unhandled
    signal.signal(signal.SIGTERM, previous)


def outcome(fn, *args, **kwargs) -> BaseException | None:
    """What ``fn`` raised, KeyboardInterrupt included (so that it fails a test, not pytest)."""
    try:
        fn(*args, **kwargs)
    except BaseException as err:  # noqa: BLE001 - the test inspects it
        return err
    return None


@pytest.mark.parametrize("how", [ctrl_c, sigterm], ids=["ctrl-c", "sigterm"])
def test_an_interrupt_between_moves_stops_the_arm_and_keeps_the_views(tmp_path, how,
                                                                      own_sigterm):
    arm, camera = rig()
    out = tmp_path / "rec.mcap"
    err = outcome(capture_to_file, arm, camera, model(), plan_for(3), out, {},
                  progress=interrupt_at(2, how))
    assert isinstance(err, UserAbort), repr(err)
    assert "interrupted; 2 view(s) kept" in str(err)
    assert signal.getsignal(signal.SIGTERM) is own_sigterm
    assert stops(arm) == 1
    assert arm.history[-1][0] == "stop"
    rec = Recording.open(out)
    assert rec.indexed and [v.index for v in rec.views] == [0, 1] and len(rec) == 1


def test_sigterm_is_an_interrupt_inside_and_handled_as_before_outside(own_sigterm):
    with sigterm_as_interrupt():
        assert isinstance(outcome(sigterm), KeyboardInterrupt)
    assert signal.getsignal(signal.SIGTERM) is own_sigterm
    assert isinstance(outcome(sigterm), Unhandled)


def test_outside_the_main_thread_sigterm_is_left_alone():
    """Python lets only the main thread set signal handlers; a capture run from another thread
    (an application's worker) goes ahead without the SIGTERM hook instead of failing."""
    outcomes = []

    def worker():
        outcomes.append(outcome(lambda: sigterm_as_interrupt().__enter__()))

    thread = threading.Thread(target=worker)
    thread.start()
    thread.join()
    assert outcomes == [None]


@pytest.mark.parametrize("method", ["write_view", "write_pair"])
def test_a_writer_error_stops_the_arm(tmp_path, monkeypatch, method):
    original = getattr(RecordingWriter, method)
    calls = 0

    def failing(self, *args, **kwargs):
        nonlocal calls
        calls += 1
        if calls == 2:
            raise RecordingError("writing /x: No space left on device")
        return original(self, *args, **kwargs)

    monkeypatch.setattr(RecordingWriter, method, failing)
    arm, camera = rig()
    out = tmp_path / "rec.mcap"
    with pytest.raises(RecordingError, match=r"No space left .* view\(s\) kept"):
        capture_to_file(arm, camera, model(), plan_for(3), out, {}, progress=None)
    assert arm.history[-1][0] == "stop"
    assert [name for name, _ in arm.history].count("move_linear") == 2 - (method == "write_view")


# --- what is left behind ------------------------------------------------------------------------

class FailingCamera:
    """Wraps the mock camera: grab number ``n`` raises (after ``before`` ran, if given)."""

    def __init__(self, camera, n: int, before=None):
        self.camera, self.n, self.before, self.grabs = camera, n, before, 0

    def __getattr__(self, name):
        return getattr(self.camera, name)

    def grab(self, *args, **kwargs):
        self.grabs += 1
        if self.grabs == self.n:
            if self.before is not None:
                self.before()
            raise CameraTimeout("no frame within 2.0 s")
        return self.camera.grab(*args, **kwargs)


def test_a_capture_that_records_no_view_leaves_no_file_and_says_so(tmp_path):
    arm, camera = rig()
    out = tmp_path / "rec.mcap"
    with pytest.raises(CameraTimeout, match=f"no view was recorded, {out} not kept"):
        capture_to_file(arm, FailingCamera(camera, 1), model(), plan_for(2), out, {},
                        progress=None)
    assert not out.exists()


def test_a_capture_that_records_one_view_keeps_it_and_says_so(tmp_path):
    arm, camera = rig()
    out = tmp_path / "rec.mcap"
    with pytest.raises(CameraTimeout, match=rf"1 view\(s\) kept in {out}"):
        capture_to_file(arm, FailingCamera(camera, 2), model(), plan_for(2), out, {},
                        progress=None)
    assert [v.index for v in Recording.open(out).views] == [0]


def test_an_output_removed_during_the_capture_does_not_hide_the_error(tmp_path):
    """Someone deleted the file mid-capture: the camera's error is what the user sees."""
    arm, camera = rig()
    out = tmp_path / "rec.mcap"
    failing = FailingCamera(camera, 1, before=lambda: out.unlink())
    with pytest.raises(CameraTimeout):
        capture_to_file(arm, failing, model(), plan_for(1), out, {}, progress=None)
    assert arm.history[-1][0] == "stop"
