"""Run a checked tour of joint moves into a recording: move, settle, grab, record, return.

Each view is shot as capture shoots its views (:mod:`armstereo.capture.run`): wait until the
arm is steady, settle, grab, then read the actual joints (and the controller's own flange pose
where the arm reports it); the view's pose is forward kinematics of those joints. The file is
finished whatever happens (errors, Ctrl-C, SIGTERM); on any error the arm is told to stop and
every view recorded so far is kept (a run that recorded nothing leaves no file).
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from armstereo.capture.run import MOVE_TIMEOUT_MARGIN_S, _shoot, _stop_quietly
from armstereo.capture.session import sigterm_as_interrupt
from armstereo.capture.tour import JointMove, TourPlan
from armstereo.devices import Arm, Camera
from armstereo.errors import ArmstereoError, UserAbort
from armstereo.kinematics import ArmModel

log = logging.getLogger(__name__)


@dataclass
class TourResult:
    """What a tour recorded: the number of complete views."""

    views: int = 0


def record_tour(arm: Arm, camera: Camera, model: ArmModel, plan: TourPlan, out: Path,
                metadata: dict[str, str], *, image_format: str = "png",
                progress: Callable[[str], None] | None = log.info) -> TourResult:
    """Visit every view of the checked ``plan`` and record it into ``out``, then return to the
    start. Errors name how many views were kept."""
    from armstereo.recording import RecordingWriter

    plan.require_ok()  # before the file exists: a refused plan leaves nothing behind
    result = TourResult()
    metadata = {**camera.recording_metadata(), **metadata}
    writer = RecordingWriter(out, metadata=metadata, image_format=image_format)
    try:
        with sigterm_as_interrupt(), writer:
            try:
                _run(arm, camera, model, plan, writer, result, progress)
            except ArmstereoError as err:
                err.args = (f"{err}; {_kept(result, out)}",)
                raise
            except KeyboardInterrupt:
                raise UserAbort(f"interrupted; {_kept(result, out)}") from None
    except BaseException:
        if result.views == 0:  # ours and empty: no 0-view recording left behind
            Path(out).unlink(missing_ok=True)
        raise
    return result


def _run(arm: Arm, camera: Camera, model: ArmModel, plan: TourPlan, writer, result: TourResult,
         progress: Callable[[str], None] | None) -> None:
    writer.write_calibration(camera.intrinsics, arm.clock.now_ns())
    try:
        for k in range(len(plan.q_views)):
            move = plan.move_to(k)
            if move is not None:
                _say(progress, f"moving to view {k} of {len(plan.q_views)}")
                _move(arm, move)
            _shoot(arm, camera, model, plan, writer, k)
            result.views += 1
        if plan.move_home is not None:
            _say(progress, "returning to the start")
            _move(arm, plan.move_home)
        arm.wait_until_steady()
    except BaseException:
        _stop_quietly(arm)
        raise


def _move(arm: Arm, move: JointMove) -> None:
    arm.move_joints(move.q_to, move.speed, move.acceleration,
                    timeout=move.duration_s + MOVE_TIMEOUT_MARGIN_S)


def _kept(result: TourResult, out: Path) -> str:
    if result.views == 0:
        return f"no view was recorded, {out} not kept"
    return f"{result.views} view(s) kept in {out}"


def _say(progress: Callable[[str], None] | None, text: str) -> None:
    if progress is not None:
        progress(text)
