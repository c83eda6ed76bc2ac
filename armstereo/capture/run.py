"""Execute a checked capture plan: move, wait until steady, settle, grab, record.

The joint positions recorded for a view are read after the grab while the arm is steady, so
they are the arm's actual joints at exposure; camera poses come from forward kinematics of those
joints (``base`` frame), never from the commanded targets. An arm that reports its controller's
own flange pose (``joints_and_controller_pose``) has it recorded beside our FK of the same
reading, so a recording shows whether our kinematics are the arm's.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from armstereo.capture.plan import CaptureSettings, PairStep, Step
from armstereo.devices import Arm, Camera
from armstereo.frame import Frame
from armstereo.robot.arm_model import ArmModel

log = logging.getLogger(__name__)

MOVE_TIMEOUT_MARGIN_S = 10.0  # on top of the planned duration of a move

def model_metadata(model: ArmModel) -> dict[str, str]:
    """The recording metadata that identifies the software, arm model and camera mount: what
    every capture (CLI, demo, sweep) records so a replay can rebuild the same kinematics
    (including the DH table, see :mod:`armstereo.robot.source`)."""
    from armstereo import __version__
    from armstereo.robot.source import kinematics_metadata

    return {"armstereo_version": __version__, "robot": model.name,
            "urdf_sha256": model.urdf_sha256, "mount": model.mount.name,
            "mount_toml": model.mount.source, **kinematics_metadata(model)}


@dataclass
class PairResult:
    """Commanded and achieved camera baseline of one pair (m), and the scan viewpoint it was
    shot from (None for a single-line capture)."""

    pair: int
    left_view: int
    right_view: int
    commanded_m: float
    achieved_m: float
    viewpoint: int | None = None


@dataclass
class CaptureResult:
    """What a capture produced: views recorded and per-pair baselines."""

    views: int = 0
    pairs: list[PairResult] = field(default_factory=list)


class CapturePlanLike(Protocol):
    """What :func:`run_capture` needs of a checked plan (a :class:`CapturePlan`, or a scan's
    :class:`armstereo.capture.tour.ScanTour`)."""

    settings: CaptureSettings

    def require_ok(self) -> None: ...

    def steps(self) -> Iterable[Step]: ...


# Called after every recorded view with (view index, the frame, T_base_camera in base).
ViewHook = Callable[[int, Frame, np.ndarray], None]


def run_capture(arm: Arm, camera: Camera, model: ArmModel, plan: CapturePlanLike, writer,
                progress: Callable[[str], None] | None = None,
                result: CaptureResult | None = None, on_view: ViewHook | None = None
                ) -> CaptureResult:
    """Run ``plan`` (already checked) step by step and record every view into ``writer``.

    On any error the arm is told to stop before the error propagates; what was recorded so far
    stays in the writer (the caller closes it) and is counted in ``result`` if one is passed.
    ``on_view`` sees every recorded view (e.g. to choose the next viewpoint from it).
    """
    plan.require_ok()
    result = CaptureResult() if result is None else result
    writer.write_calibration(camera.intrinsics, arm.clock.now_ns())
    cameras: dict[int, np.ndarray] = {}  # view -> camera position (base, m)
    try:
        for step in plan.steps():
            _move(arm, plan, step, progress)
            if step.view is not None:
                frame, T_base_camera = _shoot(arm, camera, model, plan, writer, step.view)
                cameras[step.view] = T_base_camera[:3, 3]
                result.views += 1
                if on_view is not None:
                    on_view(step.view, frame, T_base_camera)
            if step.pair is not None:
                result.pairs.append(_record_pair(writer, step.pair, cameras))
        arm.wait_until_steady()
    except BaseException:
        _stop_quietly(arm)
        raise
    return result


def _move(arm: Arm, plan: CapturePlanLike, step: Step,
          progress: Callable[[str], None] | None) -> None:
    if step.move == "none":
        return
    if step.say:
        _say(progress, step.say)
    lim = plan.settings.limits
    if step.move == "linear":
        arm.move_linear(step.target, lim.linear_speed, lim.linear_acceleration,
                        timeout=step.duration_s + MOVE_TIMEOUT_MARGIN_S)
    elif step.move == "joints":
        arm.move_joints(step.target, lim.joint_speed, lim.joint_acceleration,
                        timeout=step.duration_s + MOVE_TIMEOUT_MARGIN_S)
    else:
        raise ValueError(f"unknown move kind {step.move!r}")


def _shoot(arm: Arm, camera: Camera, model: ArmModel, plan: CapturePlanLike, writer, k: int
           ) -> tuple[Frame, np.ndarray]:
    """Settle, grab, read the actual joints and write view ``k``; returns the frame and the
    camera pose (T_base_camera, FK of the actual joints)."""
    arm.wait_until_steady()
    arm.clock.sleep(plan.settings.settle_s)
    arm.require_ok()
    frame = camera.grab()
    read_both = getattr(arm, "joints_and_controller_pose", None)
    q, T_controller = read_both() if callable(read_both) else (arm.joint_positions(), None)
    T_base_flange = model.flange_pose(q)
    writer.write_view(k, frame, q, model.joint_names, T_base_flange, model.mount.T_flange_camera,
                      settle_s=plan.settings.settle_s, controller_T_base_flange=T_controller)
    log.debug("view %d recorded at q=%s", k, np.round(q, 5))
    return frame, T_base_flange @ model.mount.T_flange_camera


def _record_pair(writer, step: PairStep, cameras: dict[int, np.ndarray]) -> PairResult:
    achieved = float(np.linalg.norm(cameras[step.right_view] - cameras[step.left_view]))
    pr = PairResult(step.pair, step.left_view, step.right_view, step.commanded_m, achieved,
                    step.viewpoint)
    writer.write_pair(pr.pair, pr.left_view, pr.right_view, pr.commanded_m, pr.achieved_m,
                      step.direction, viewpoint=step.viewpoint)
    log.debug("pair %d: baseline commanded %.2f mm, achieved %.3f mm", pr.pair,
              pr.commanded_m * 1000, pr.achieved_m * 1000)
    return pr


def _stop_quietly(arm: Arm) -> None:
    try:
        arm.stop()
    except Exception as err:  # noqa: BLE001 - the original error matters more
        log.warning("could not stop the arm after an error: %s", err)


def _say(progress: Callable[[str], None] | None, text: str) -> None:
    if progress is not None:
        progress(text)
