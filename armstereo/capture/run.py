"""Execute a checked capture plan: move, wait until steady, settle, grab, record.

The joint positions recorded for a view are read after the grab while the arm is steady, so
they are the arm's actual joints at exposure; camera poses come from forward kinematics of those
joints (``base`` frame), never from the commanded targets. An arm that reports its controller's
own flange pose (``joints_and_controller_pose``) has it recorded beside our FK of the same
reading, so a recording shows whether our kinematics are the arm's.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from armstereo.capture.plan import CapturePlan
from armstereo.devices import Arm, Camera
from armstereo.kinematics import ArmModel

log = logging.getLogger(__name__)

MOVE_TIMEOUT_MARGIN_S = 10.0  # on top of the planned duration of a move


def model_metadata(model: ArmModel) -> dict[str, str]:
    """The recording metadata that identifies the software, arm model and camera mount: what
    every capture (CLI, demo, sweep) records so a replay can rebuild the same kinematics
    (including the DH table, see :mod:`armstereo.capture.kinematics`)."""
    from armstereo import __version__
    from armstereo.capture.kinematics import kinematics_metadata

    return {"armstereo_version": __version__, "robot": model.name,
            "urdf_sha256": model.urdf_sha256, "mount": model.mount.name,
            "mount_toml": model.mount.source, **kinematics_metadata(model)}


@dataclass
class PairResult:
    """Commanded and achieved camera baseline of one pair (m)."""

    pair: int
    left_view: int
    right_view: int
    commanded_m: float
    achieved_m: float


@dataclass
class CaptureResult:
    """What a capture produced: views recorded and per-pair baselines."""

    views: int = 0
    pairs: list[PairResult] = field(default_factory=list)


def run_capture(arm: Arm, camera: Camera, model: ArmModel, plan: CapturePlan, writer,
                progress: Callable[[str], None] | None = None,
                result: CaptureResult | None = None) -> CaptureResult:
    """Run ``plan`` (already checked) and record every view into ``writer``.

    On any error the arm is told to stop before the error propagates; what was recorded so far
    stays in the writer (the caller closes it) and is counted in ``result`` if one is passed.
    """
    plan.require_ok()
    result = CaptureResult() if result is None else result
    lim = plan.settings.limits
    writer.write_calibration(camera.intrinsics, arm.clock.now_ns())
    prev_camera = None
    try:
        for k, T_target in enumerate(plan.T_base_flange):
            if k > 0:
                _say(progress, f"moving to view {k}")
                arm.move_linear(T_target, lim.linear_speed, lim.linear_acceleration,
                                timeout=_move_timeout(plan))
            camera_pos = _shoot(arm, camera, model, plan, writer, k)
            result.views += 1
            if prev_camera is not None:
                result.pairs.append(_record_pair(writer, plan, k, prev_camera, camera_pos))
            prev_camera = camera_pos
        _say(progress, "returning to the start")
        arm.move_linear(plan.T_base_flange[0], lim.linear_speed, lim.linear_acceleration,
                        timeout=_move_timeout(plan))
        arm.wait_until_steady()
    except BaseException:
        _stop_quietly(arm)
        raise
    return result


def _shoot(arm: Arm, camera: Camera, model: ArmModel, plan: CapturePlan, writer, k: int):
    """Settle, grab, read the actual joints and write view ``k``; returns the camera position."""
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
    return (T_base_flange @ model.mount.T_flange_camera)[:3, 3]


def _record_pair(writer, plan: CapturePlan, k: int, prev: np.ndarray, cur: np.ndarray):
    achieved = float(np.linalg.norm(cur - prev))
    pr = PairResult(k - 1, k - 1, k, plan.settings.baseline, achieved)
    writer.write_pair(pr.pair, pr.left_view, pr.right_view, pr.commanded_m, pr.achieved_m,
                      plan.settings.direction_label)
    log.debug("pair %d: baseline commanded %.2f mm, achieved %.3f mm", pr.pair,
             pr.commanded_m * 1000, pr.achieved_m * 1000)
    return pr


def _move_timeout(plan: CapturePlan) -> float:
    return plan.duration_s + MOVE_TIMEOUT_MARGIN_S


def _stop_quietly(arm: Arm) -> None:
    try:
        arm.stop()
    except Exception as err:  # noqa: BLE001 - the original error matters more
        log.warning("could not stop the arm after an error: %s", err)


def _say(progress: Callable[[str], None] | None, text: str) -> None:
    if progress is not None:
        progress(text)
