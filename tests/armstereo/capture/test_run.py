"""The capture loop's safety (``run_capture``): every error ends with the arm told to stop,
whichever device raised it and whenever (Hypothesis picks the device, the call and the
error, Ctrl-C included); each shot is taken only after the arm is at rest, has settled and
reports a normal state, from a frame exposed after that; pairs name their views in order.

The arm is the mock arm on a simulated clock; camera and writer are small fakes that log every
call, with the clock time, into one shared list, so the order across devices can be checked.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from functools import cache

import numpy as np
import pytest
from hypothesis import given
from hypothesis import settings as hyp_settings
from hypothesis import strategies as st

from armstereo.camera_model import Intrinsics
from armstereo.capture import CaptureSettings, plan_capture, run_capture
from armstereo.capture.plan import PairStep, Step, parse_direction
from armstereo.capture.run import MOVE_TIMEOUT_MARGIN_S
from armstereo.clock import SimClock
from armstereo.devices import ArmState, Camera, Frame
from armstereo.errors import (
    CameraTimeout,
    ConnectionLost,
    EmergencyStop,
    MotionTimeout,
    PreflightError,
    ProtectiveStop,
    RecordingError,
)
from armstereo.robot.arm_model import ArmModel
from drivers.mock.arm import MockArm
from drivers.mock.start_poses import table_start
from tests.support.properties import examples

SETTLE_S = 0.3


@cache
def model() -> ArmModel:
    return ArmModel.load("ur5e", mount="default_wrist_camera")


class Injected:
    """Which call fails: the ``n``-th call (1-based) of ``site`` raises ``error``."""

    def __init__(self, site: str = "", n: int = 0, error: BaseException | None = None):
        self.site, self.n, self.error = site, n, error
        self.counts: dict[str, int] = {}
        self.fired = False

    def visit(self, site: str) -> None:
        self.counts[site] = self.counts.get(site, 0) + 1
        if site == self.site and self.counts[site] == self.n and not self.fired:
            self.fired = True
            raise self.error


class Rig:
    """Mock arm, fake camera and fake writer sharing one clock, one call log and one fault."""

    def __init__(self, fault: Injected | None = None, stop_raises: bool = False):
        self.fault = fault or Injected()
        self.log: list[tuple[str, int, object]] = []  # (site, clock time ns, detail)
        self.clock = LoggedClock(self)
        self.arm = LoggedArm(self, model(), table_start(model()), clock=self.clock)
        self.arm.stop_raises = stop_raises
        self.camera = FakeCamera(self)
        self.writer = FakeWriter(self)
        self.arm.connect()
        self.camera.connect()

    def enter(self, site: str, detail: object = None) -> None:
        self.log.append((site, self.clock.now_ns(), detail))
        self.fault.visit(site)

    def sites(self) -> list[str]:
        return [s for s, _, _ in self.log]

    def run(self, plan):
        return run_capture(self.arm, self.camera, model(), plan, self.writer,
                           progress=lambda text: self.enter("progress", text))


class LoggedClock(SimClock):
    def __init__(self, rig: Rig):
        super().__init__()
        self.rig = rig

    def sleep(self, seconds: float) -> None:
        self.rig.log.append(("clock.sleep", self.now_ns(), seconds))
        self.rig.fault.visit("clock.sleep")
        super().sleep(seconds)


class LoggedArm(MockArm):
    stop_raises = False

    def __init__(self, rig: Rig, *args, **kwargs):
        self.rig = rig
        super().__init__(*args, **kwargs)

    def move_linear(self, *args, **kwargs):
        self.rig.enter("arm.move_linear")
        super().move_linear(*args, **kwargs)
        self.rig.log.append(("arm.moved", self.clock.now_ns(), None))

    def wait_until_steady(self, timeout: float = 10.0):
        self.rig.enter("arm.wait_until_steady")
        super().wait_until_steady(timeout)

    def status(self):
        if getattr(self, "rig", None) is not None:
            self.rig.enter("arm.status")
        return super().status()

    def joint_positions(self):
        self.rig.enter("arm.joint_positions")
        q = super().joint_positions()
        self.rig.log.append(("arm.q", self.clock.now_ns(), q.copy()))
        return q

    def joints_and_controller_pose(self):
        # the loop reads the joints this way when the arm offers it (one RTDE package)
        self.rig.enter("arm.joint_positions")
        q, T = super().joints_and_controller_pose()
        self.rig.log.append(("arm.q", self.clock.now_ns(), q.copy()))
        return q, T

    def stop(self):
        self.rig.log.append(("arm.stop", self.clock.now_ns(), None))
        super().stop()
        if self.stop_raises:
            raise ConnectionLost("the link is down too")


class FakeCamera(Camera):
    name = "fake camera"

    def __init__(self, rig: Rig):
        self.rig = rig
        self._intrinsics = Intrinsics(32, 24, np.array([[30.0, 0, 16], [0, 30.0, 12], [0, 0, 1]]))

    def connect(self):
        self._connected = True

    def close(self):
        self._connected = False

    @property
    def intrinsics(self):
        return self._intrinsics

    def grab(self, timeout: float = 2.0) -> Frame:
        self.rig.enter("camera.grab")
        self.rig.clock.advance_ns(10_000_000)  # the exposure after the call began
        frame = Frame(np.zeros((24, 32), np.uint8), self.rig.clock.now_ns())
        self.rig.log.append(("camera.frame", self.rig.clock.now_ns(), frame))
        return frame


class FakeWriter:
    def __init__(self, rig: Rig):
        self.rig = rig
        self.views: list[dict] = []
        self.pairs: list[tuple[int, int, int]] = []
        self.baselines: list[tuple[float, float, str]] = []

    def write_calibration(self, intrinsics, t_ns):
        self.rig.enter("writer.write_calibration")

    def write_view(self, view, frame, q, joint_names, T_base_flange, T_flange_camera, *,
                   settle_s, controller_T_base_flange=None):
        self.rig.enter("writer.write_view", view)
        self.views.append(dict(view=view, frame=frame, q=np.array(q), T=T_base_flange,
                               settle_s=settle_s, controller_T=controller_T_base_flange))

    def write_pair(self, pair, left_view, right_view, commanded, achieved, direction, *,
                   viewpoint=None):
        self.rig.enter("writer.write_pair", (pair, left_view, right_view))
        self.pairs.append((pair, left_view, right_view))
        self.baselines.append((commanded, achieved, direction))


def make_plan(pairs: int = 2, baseline: float = 0.05, direction: str = "x", **kw):
    d, label = parse_direction(direction)
    s = CaptureSettings(baseline=baseline, direction=d, direction_label=label, pairs=pairs,
                        settle_s=SETTLE_S, **kw)
    plan = plan_capture(model(), table_start(model()), s)
    assert plan.ok, plan.describe()
    return plan


# --- every error ends with the arm told to stop ---------------------------------------------

SITES = ["arm.move_linear", "arm.wait_until_steady", "arm.status", "arm.joint_positions",
         "camera.grab", "writer.write_view", "writer.write_pair", "progress", "clock.sleep"]
ERRORS = [KeyboardInterrupt, lambda: ProtectiveStop("protective stop"),
          lambda: EmergencyStop("e-stop"), lambda: ConnectionLost("link down"),
          lambda: MotionTimeout("stuck"), lambda: CameraTimeout("no frame"),
          lambda: RecordingError("disk full"), lambda: OSError(28, "No space left on device"),
          lambda: RuntimeError("a bug")]


@hyp_settings(max_examples=examples(80))
@given(site=st.sampled_from(SITES), n=st.integers(1, 6), error=st.sampled_from(ERRORS),
       pairs=st.integers(1, 3), stop_raises=st.booleans())
def test_every_error_during_a_capture_ends_with_the_arm_told_to_stop(site, n, error, pairs,
                                                                     stop_raises):
    err = error()
    rig = Rig(Injected(site, n, err), stop_raises=stop_raises)
    plan = make_plan(pairs)
    try:
        rig.run(plan)
    except BaseException as raised:  # noqa: BLE001 - the test inspects what came out
        assert raised is err  # the original error, even when the stop itself fails
    else:
        assert not rig.fault.fired
        return
    sites = rig.sites()
    failed = max(i for i, (s, _, _) in enumerate(rig.log) if s == site)
    after = sites[failed + 1:]
    assert "arm.stop" in after, f"{site} #{n} raised {err!r}; the arm was not told to stop"
    assert "arm.move_linear" not in after[after.index("arm.stop"):]
    assert "camera.grab" not in after and "writer.write_view" not in after


def test_a_writer_error_before_the_first_view_moves_nothing():
    rig = Rig(Injected("writer.write_calibration", 1, RecordingError("read-only")))
    with pytest.raises(RecordingError):
        rig.run(make_plan())
    assert "arm.move_linear" not in rig.sites() and "camera.grab" not in rig.sites()


def test_a_plan_that_failed_pre_flight_moves_nothing():
    rig = Rig()
    plan = make_plan()
    bad = replace(plan, checks=[*plan.checks[:-1], replace(plan.checks[-1], ok=False)])
    with pytest.raises(PreflightError, match="nothing moved"):
        rig.run(bad)
    assert rig.log == []


@pytest.mark.parametrize("fault", ["disconnect@2", "protective-stop@1", "stuck-move@2"])
def test_mock_arm_faults_end_with_a_stop_request(fault):
    from drivers.mock.faults import FaultPlan

    rig = Rig()
    rig.arm.faults = FaultPlan.parse([fault])
    with pytest.raises((ConnectionLost, ProtectiveStop, MotionTimeout)):
        rig.run(make_plan())
    assert rig.sites()[-1] == "arm.stop"


def test_a_stuck_move_is_abandoned_within_the_plans_time_and_the_arm_stopped():
    """The loop gives every move the whole plan's estimated time plus a margin, no more: a
    move that never arrives ends in MotionTimeout and a stop by then."""
    from armstereo.capture.run import MOVE_TIMEOUT_MARGIN_S
    from drivers.mock.faults import FaultPlan

    rig = Rig()
    rig.arm.faults = FaultPlan.parse(["stuck-move@2"])
    plan = make_plan(pairs=2)
    with pytest.raises(MotionTimeout):
        rig.run(plan)
    moves = [t for s, t, _ in rig.log if s == "arm.move_linear"]
    stop = next(t for s, t, _ in rig.log if s == "arm.stop")
    waited = (stop - moves[-1]) * 1e-9
    assert plan.duration_s <= waited <= plan.duration_s + MOVE_TIMEOUT_MARGIN_S + 1e-6


# --- the checks before each shot ------------------------------------------------------------

def shots(rig: Rig) -> list[list[tuple[str, int, object]]]:
    """The log cut into views: from the start or the end of a move to the view's write."""
    out, cur = [], []
    for entry in rig.log:
        cur.append(entry)
        if entry[0] == "writer.write_view":
            out.append(cur)
            cur = []
    return out


@hyp_settings(max_examples=examples(15))
@given(pairs=st.integers(1, 4), baseline=st.floats(0.01, 0.1),
       direction=st.sampled_from(["x", "-x", "y", "-y", "1,1,0.3"]),
       settle=st.floats(0.0, 2.0))
def test_each_shot_waits_for_rest_settles_checks_the_arm_and_uses_a_fresh_frame(
        pairs, baseline, direction, settle):
    rig = Rig()
    plan = make_plan(pairs, baseline, direction)
    plan = replace(plan, settings=replace(plan.settings, settle_s=settle))
    rig.run(plan)
    views = shots(rig)
    assert len(views) == pairs + 1 == len(rig.writer.views)
    for k, (view, written) in enumerate(zip(views, rig.writer.views, strict=True)):
        sites = [s for s, _, _ in view]
        last_move = max((i for i, s in enumerate(sites) if s == "arm.moved"), default=-1)
        assert (last_move >= 0) == (k > 0)  # view k > 0 is shot after the move to it
        steady = sites.index("arm.wait_until_steady", last_move + 1)
        grab = sites.index("camera.grab", steady)
        settled_ns = view[steady][1] + round(settle * 1e9)
        # a normal state is confirmed after the settle time and before the grab
        checks = [i for i in range(steady, grab) if sites[i] == "arm.status"]
        assert checks and view[checks[-1]][1] >= settled_ns
        frame = view[sites.index("camera.frame", grab)][2]
        assert frame.timestamp_ns >= settled_ns  # exposed after settling
        assert written["frame"] is frame and written["view"] == k
        assert written["settle_s"] == settle
        # the joints recorded are read after the exposure, not the commanded ones
        q_read = [d for s, _, d in view[grab:] if s == "arm.q"]
        assert q_read and np.array_equal(written["q"], q_read[-1])
        np.testing.assert_allclose(written["T"], model().flange_pose(q_read[-1]), atol=1e-12)


@hyp_settings(max_examples=examples(20))
@given(view=st.integers(0, 3), state=st.sampled_from([ArmState.PROTECTIVE_STOP,
                                                      ArmState.EMERGENCY_STOP,
                                                      ArmState.DISCONNECTED]))
def test_no_shot_is_taken_of_an_arm_that_is_not_in_a_normal_state(view, state):
    """The arm stops (here: while settling before view ``view``) without any move failing."""
    rig = Rig()
    plan = make_plan(pairs=3)
    settles = 0
    sleep = rig.clock.sleep

    def settle_then_stop(seconds):
        nonlocal settles
        sleep(seconds)
        if seconds == SETTLE_S:
            settles += 1
            if settles == view + 1:
                rig.arm._state, rig.arm._detail = state, "tripped while settling"

    rig.clock.sleep = settle_then_stop
    with pytest.raises((ProtectiveStop, EmergencyStop, ConnectionLost)):
        rig.run(plan)
    assert [v["view"] for v in rig.writer.views] == list(range(view))
    assert "arm.stop" in rig.sites()


def test_recorded_pairs_name_consecutive_views_left_then_right():
    rig = Rig()
    rig.run(make_plan(pairs=3))
    assert rig.writer.pairs == [(0, 0, 1), (1, 1, 2), (2, 2, 3)]


@pytest.mark.parametrize("direction", ["x", "-y", "1,1,0.8"])
def test_pairs_report_the_commanded_and_the_achieved_camera_baseline(direction):
    """The achieved baseline is the distance between the recorded camera positions (forward
    kinematics of the joints read at each shot), in 3D; the mock arm's joint noise makes it
    differ from the commanded one."""
    rig = Rig()
    rig.arm.joint_noise = 2e-4
    plan = make_plan(pairs=2, baseline=0.06, direction=direction)
    result = rig.run(plan)
    T_fc = model().mount.T_flange_camera
    cams = [(v["T"] @ T_fc)[:3, 3] for v in rig.writer.views]
    for k, (pr, written) in enumerate(zip(result.pairs, rig.writer.baselines, strict=True)):
        achieved = float(np.linalg.norm(cams[k + 1] - cams[k]))
        assert (pr.pair, pr.left_view, pr.right_view) == (k, k, k + 1)
        assert pr.commanded_m == written[0] == 0.06
        assert pr.achieved_m == pytest.approx(achieved, abs=1e-12) and written[1] == pr.achieved_m
        assert abs(pr.achieved_m - 0.06) > 1e-7  # the noise is there, so this is no copy
        assert written[2] == plan.settings.direction_label


def test_the_arm_returns_to_the_start_and_ends_at_rest():
    rig = Rig()
    plan = make_plan(pairs=2)
    result = rig.run(plan)
    assert result.views == 3 and [p.pair for p in result.pairs] == [0, 1]
    sites = rig.sites()
    assert sites.count("arm.move_linear") == 3
    assert sites[-1] == "arm.wait_until_steady" and "arm.stop" not in sites
    last = rig.arm.history[-2]
    assert last[0] == "move_linear"
    np.testing.assert_allclose(last[1]["T_base_flange"], plan.T_base_flange[0], atol=1e-12)
    assert last[1]["speed"] == plan.settings.limits.linear_speed
    assert last[1]["acceleration"] == plan.settings.limits.linear_acceleration


# --- each kind of move, and the joints read with each shot -------------------------------------

class MoveSpy(LoggedArm):
    """Also keeps what each move was asked: (kind, speed, acceleration, timeout)."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self.moves: list[tuple[str, float, float, float]] = []

    def move_linear(self, T, speed, acceleration, timeout=None):
        self.moves.append(("linear", speed, acceleration, timeout))
        super().move_linear(T, speed, acceleration, timeout=timeout)

    def move_joints(self, q, speed, acceleration, timeout=None):
        self.moves.append(("joints", speed, acceleration, timeout))
        super().move_joints(q, speed, acceleration, timeout=timeout)


@dataclass
class StepPlan:
    """A checked plan given as its steps (what a scan tour hands the loop)."""

    settings: CaptureSettings
    given: list[Step]

    def require_ok(self) -> None:
        pass

    def steps(self) -> list[Step]:
        return self.given


def kind(name: str) -> str:
    """``name`` as a string object of its own, as a plan read from a file would carry: kinds
    are compared by value, not by identity with the module's literals."""
    return "".join(list(name))


def spy_rig() -> Rig:
    rig = Rig()
    rig.arm = MoveSpy(rig, model(), table_start(model()), clock=rig.clock)
    rig.arm.connect()
    return rig


def test_each_move_kind_runs_at_its_caps_with_the_plans_time_plus_the_margin():
    rig = spy_rig()
    plan = make_plan(pairs=1)
    lim = plan.settings.limits
    steps = [Step(kind("none"), None, 1.0, view=0),
             Step(kind("joints"), plan.q_views[1], 2.5, view=1,
                  pair=PairStep(0, 0, 1, 0.05, "x")),
             Step(kind("linear"), plan.T_base_flange[0], 3.5)]
    rig.run(StepPlan(plan.settings, steps))
    assert rig.arm.moves == [
        ("joints", lim.joint_speed, lim.joint_acceleration, 2.5 + MOVE_TIMEOUT_MARGIN_S),
        ("linear", lim.linear_speed, lim.linear_acceleration, 3.5 + MOVE_TIMEOUT_MARGIN_S)]
    assert [v["view"] for v in rig.writer.views] == [0, 1]
    assert rig.writer.pairs == [(0, 0, 1)]


@pytest.mark.parametrize("name", ["wiggle", "hover", "Linear", ""])
def test_an_unknown_move_kind_is_refused_and_the_arm_stopped(name):
    """Kinds sorting before and after every known one: no prefix or order test may pass."""
    rig = spy_rig()
    plan = make_plan(pairs=1)
    steps = [Step(kind("none"), None, 1.0, view=0),
             Step(kind(name), plan.T_base_flange[1], 2.0, view=1)]
    with pytest.raises(ValueError, match="unknown move kind"):
        rig.run(StepPlan(plan.settings, steps))
    assert rig.arm.moves == [] and "arm.stop" in rig.sites()


def test_each_view_keeps_the_controllers_pose_when_the_arm_reports_one():
    rig = Rig()
    rig.run(make_plan(pairs=1))
    for written in rig.writer.views:
        np.testing.assert_allclose(written["controller_T"], model().flange_pose(written["q"]),
                                   atol=1e-12)


class ArmWithoutControllerPose(LoggedArm):
    joints_and_controller_pose = None  # an arm whose interface has only joint_positions()


def test_an_arm_without_a_controller_pose_records_its_joints_alone():
    rig = Rig()
    rig.arm = ArmWithoutControllerPose(rig, model(), table_start(model()), clock=rig.clock)
    rig.arm.connect()
    rig.run(make_plan(pairs=1))
    assert len(rig.writer.views) == 2
    assert all(v["controller_T"] is None for v in rig.writer.views)

