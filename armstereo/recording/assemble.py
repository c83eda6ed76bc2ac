"""Assembly: turn collected messages into views, pairs and warnings."""

from __future__ import annotations

import json
from typing import TYPE_CHECKING

import numpy as np

from armstereo.camera_model import Intrinsics
from armstereo.recording import schemas as S
from armstereo.recording.collect import Collector
from armstereo.recording.contents import ChannelInfo, Pair, View
from armstereo.recording.decode import image_size_from_header

if TYPE_CHECKING:
    from armstereo.recording.contents import RecordingContents

BASELINE_TOLERANCE_M = 1e-4  # event vs poses: larger differences are reported
# Our FK vs the controller's own flange pose: with the controller's calibrated table they agree
# to ~1e-12 m; beyond this the kinematic model is not this arm's.
FK_VS_CONTROLLER_TOLERANCE_M = 1e-4
# /tf against the recorded DH table's FK of the recorded joints (m, and rad for rotations):
# the two are one computation, so only float rounding separates them.
RECORDED_TABLE_TOLERANCE_M = 1e-9


def assemble(rec: RecordingContents, col: Collector) -> None:
    """Turn collected messages into views, pairs and warnings."""
    rec.metadata_records = dict(col.metadata)
    rec.metadata = dict(col.metadata.get(S.METADATA_NAME, {}))
    if S.METADATA_NAME not in col.metadata:
        rec._warn(f"no '{S.METADATA_NAME}' metadata record (robot, mount, capture settings)")
    rec.channels = [ChannelInfo(*info) for info in col.channel_table()]
    rec.start_ns, rec.end_ns = col.first_ns, col.last_ns
    rec.point_clouds = list(col.point_clouds)
    for text in col.problems():
        rec._warn(text)
    for text in col.missing_against_statistics():
        rec._lose(text)
    _set_calibration(rec, col)
    _build_views(rec, col)
    _build_pairs(rec, col)
    _check_pairs_asked(rec)
    _check_kinematics(rec)
    if col.first_ns is None:
        rec._warn("the recording holds no readable message")


def _check_pairs_asked(rec: RecordingContents) -> None:
    """An interrupted capture holds fewer pairs than its metadata asked for: say so."""
    try:
        asked = int(rec.metadata.get("pairs", ""))
    except ValueError:
        return
    got = len(rec._pairs)
    if got < asked:
        rec._warn(f"the capture asked for {asked} pair(s) but {got} complete pair(s) were "
                  "recorded (interrupted or failed?)")


def _set_calibration(rec: RecordingContents, col: Collector) -> None:
    if not col.calibrations:
        rec._warn(f"no camera calibration ({S.TOPIC_CALIBRATION}): pairs cannot be used")
        return
    first = col.calibrations[0]
    rec.calibration = first.intrinsics
    rec.calibration_info = {"frame_id": first.frame_id,
                            "distortion_model": first.distortion_model}
    if first.frame_id != S.FRAME_CAMERA:
        rec._warn(f"calibration frame_id is '{first.frame_id}', expected '{S.FRAME_CAMERA}'")


def _intrinsics_at(col: Collector, t_ns: int) -> Intrinsics | None:
    best = None
    for cal in col.calibrations:  # sorted by time: the latest one not after t_ns
        if best is None or cal.t_ns <= t_ns:
            best = cal
    return None if best is None else best.intrinsics


def _build_views(rec: RecordingContents, col: Collector) -> None:
    claimed: set[int] = set()
    for index in sorted(col.view_events):
        t_ns, settle_s, controller = col.view_events[index]
        missing = [topic for topic, table in ((S.TOPIC_IMAGE, col.images), (S.TOPIC_TF, col.tf))
                   if t_ns not in table]
        if missing:
            rec._lose(f"view {index} is incomplete (no {' or '.join(missing)} message at "
                      f"{t_ns} ns); skipped")
            continue
        claimed.add(t_ns)
        view = _make_view(rec, col, index, t_ns, settle_s)
        view.controller_T_base_flange = controller
        rec.views.append(view)
    for topic, table in ((S.TOPIC_IMAGE, col.images), (S.TOPIC_TF, col.tf),
                         (S.TOPIC_DEPTH, col.depth)):
        orphans = len(set(table) - claimed)
        if orphans:
            rec._lose(f"{orphans} message(s) on {topic} belong to no complete view (a view "
                      "cut short?)")


def _make_view(rec: RecordingContents, col: Collector, index: int, t_ns: int,
               settle_s: float) -> View:
    fmt, data = col.images[t_ns]
    frames = col.tf[t_ns]
    intr = _intrinsics_at(col, t_ns)
    joints = col.joints.get(index)
    if joints is None or joints[0] != t_ns:
        rec._warn(f"view {index} has no joint states on {S.TOPIC_JOINT_STATES}")
        joints = None
    size = image_size_from_header(data, fmt)
    if size is not None and intr is not None and size != intr.size:
        rec._warn(f"view {index}: image is {size[0]}x{size[1]} but the calibration says "
                  f"{intr.width}x{intr.height}")
    for name, norm in frames.quaternion_norms.items():
        if abs(norm - 1.0) > 1e-6:
            rec._warn(f"view {index}: {name} rotation quaternion has norm {norm:.6f}, not 1 "
                      "(not a rotation)")
    return View(index=index, timestamp_ns=t_ns, T_base_flange=frames.T_base_flange,
                T_flange_camera=frames.T_flange_camera, intrinsics=intr,
                joint_names=tuple(joints[1]) if joints else (),
                joint_positions=np.array(joints[2], dtype=float) if joints else None,
                settle_s=settle_s, image_format=fmt, image_size=size, _image_data=data,
                _depth_msg=col.depth.get(t_ns))


def _build_pairs(rec: RecordingContents, col: Collector) -> None:
    views = {v.index: v for v in rec.views}
    for event in col.pair_events:
        rec.pair_events.append(event)
        left, right = views.get(event["left_view"]), views.get(event["right_view"])
        if left is None or right is None:
            gone = [k for k, v in ((event["left_view"], left), (event["right_view"], right))
                    if v is None]
            rec._lose(f"pair {event['pair']} is incomplete (view {', '.join(map(str, gone))} "
                      "missing); skipped")
            continue
        pair = Pair(event["pair"], left, right, event["commanded_baseline_m"],
                    event["achieved_baseline_m"], event["direction"], event["viewpoint"])
        _check_baseline(rec, pair)
        rec._pairs.append(pair)


def fk_vs_controller(view: View) -> tuple[float, float] | None:
    """(translation m, rotation rad) between the view's recorded FK flange pose and the
    controller's reported one; None if the controller's was not recorded."""
    if view.controller_T_base_flange is None:
        return None
    from armstereo.robot.dh import pose_difference

    lin, ang = pose_difference(view.T_base_flange, view.controller_T_base_flange)
    return float(lin), float(ang)


def _check_kinematics(rec: RecordingContents) -> None:
    """Warn when the recorded poses are not the arm's: FK far from the controller's own pose,
    or a real arm captured with nominal kinematics."""
    worst = max(((d, v.index) for v in rec.views if (d := fk_vs_controller(v)) is not None),
                default=None)
    if worst is not None and worst[0][0] > FK_VS_CONTROLLER_TOLERANCE_M:
        (lin, ang), index = worst
        rec._warn(f"view {index}: our forward kinematics is {lin * 1000:.3f} mm / "
                  f"{np.degrees(ang):.4f} deg from the controller's own flange pose (limit "
                  f"{FK_VS_CONTROLLER_TOLERANCE_M * 1000:g} mm): the kinematic model is not "
                  f"this arm's, so camera poses are off")
    _check_recorded_table(rec)
    if rec.metadata.get("arm") == "ur" and rec.metadata.get("kinematics_source") == "nominal":
        rec._warn("captured on a real arm with NOMINAL kinematics (the controller's calibrated "
                  "table was not read): camera poses may be off by millimetres")


def _check_recorded_table(rec: RecordingContents) -> None:
    """The /tf flange poses must be the recorded table's FK of the recorded joints: that is
    what reconstruction uses. Warn for the first view where they are not."""
    text = rec.metadata.get("dh_table")
    views = [v for v in rec.views if v.joint_positions is not None
             and v.joint_positions.shape == (6,)]
    if not text or not views:
        return
    from armstereo.errors import ArmstereoError
    from armstereo.robot.dh import DHTable, fk, pose_difference

    try:
        values = json.loads(text)
        table = DHTable(model="", theta=values["theta"], a=values["a"], d=values["d"],
                        alpha=values["alpha"])
    except (ValueError, TypeError, KeyError, ArmstereoError) as err:
        rec._warn(f"metadata dh_table is not a DH table ({type(err).__name__}); /tf used as is")
        return
    for v in views:
        lin, ang = pose_difference(fk(table, v.joint_positions), v.T_base_flange)
        if lin > RECORDED_TABLE_TOLERANCE_M or ang > RECORDED_TABLE_TOLERANCE_M:
            rec._warn(f"view {v.index}: the {S.TOPIC_TF} flange pose is {lin * 1000:.3f} mm "
                      f"from the recorded dh_table's FK of its joints: the poses were not "
                      f"computed with the recorded kinematics")
            return


def _check_baseline(rec: RecordingContents, pair: Pair) -> None:
    from_poses = float(np.linalg.norm(pair.right.T_base_camera[:3, 3]
                                      - pair.left.T_base_camera[:3, 3]))
    if abs(from_poses - pair.achieved_baseline_m) > BASELINE_TOLERANCE_M:
        rec._warn(f"pair {pair.index}: achieved baseline {pair.achieved_baseline_m * 1000:.3f} mm "
                  f"in the event but {from_poses * 1000:.3f} mm from the {S.TOPIC_TF} poses "
                  f"(limit {BASELINE_TOLERANCE_M * 1000:.1f} mm)")


