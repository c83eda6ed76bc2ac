"""``armstereo import BAG --image-topic T --out REC.mcap``: a ROS 2 bag as armstereo recordings.

Views are the images shot while the camera was at rest (:mod:`armstereo.ros2.rest`); a bag
exported by armstereo carries its views and pairs on ``/capture/events``, which are used as
they are (the import of an export gives the recording back). Each view's camera pose comes
from the TF tree at the image's stamp (``base -> tool0 -> camera frame``), or, with
``robot``, from the joint states through that arm's kinematics and the camera mount. With a
``board``, the views that see it also go into a calibration recording for
``armstereo calibrate --from``.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from armstereo import validate
from armstereo.calibration.board import Board, detect_board
from armstereo.calibration.session import calibration_metadata
from armstereo.errors import ConfigError, RecordingError
from armstereo.kinematics import JOINT_NAMES, ArmModel
from armstereo.mount import CameraMount
from armstereo.ros2 import types as R
from armstereo.ros2.bag_contents import Contents, Topics, collect, load_depth, load_images
from armstereo.ros2.bag_reader import BagReader
from armstereo.ros2.export import CUSTOM_PREFIX
from armstereo.ros2.import_write import ViewRecord, write_recording
from armstereo.ros2.poses import JointPoses, TfPoses
from armstereo.ros2.rest import RestOptions, choose_pairs, rest_views, still_mask

log = logging.getLogger(__name__)

EVENTS_TOPIC = "/capture/events"
DEPTH_TOPIC = "/camera/depth_truth"
# Keys of an exported recording's metadata that describe the file, not the capture.
_NOT_RESTORED = ("format_version", "armstereo_version", "recording_kind", "source_recording")


@dataclass(frozen=True, kw_only=True)
class ImportOptions:
    """What to read and how to choose views (module doc); frames are tf2 names."""

    image_topic: str
    camera_info_topic: str | None = None  # default: camera_info beside the image topic
    tf_topic: str = R.TOPIC_TF
    tf_static_topic: str = R.TOPIC_TF_STATIC
    joint_states_topic: str = "/joint_states"
    base_frame: str = "base"
    flange_frame: str = "tool0"
    camera_frame: str | None = None  # default: the images' header frame_id
    robot: str | None = None  # model name, URDF or `robot-info --save` file
    mount: str | None = None  # for poses from joints, and the calibration recording
    baseline: float | None = None
    baseline_tolerance: float = 0.002
    rest: RestOptions = RestOptions()
    board: Board | None = None
    calibration_out: Path | None = None
    use_events: bool = True

    def __post_init__(self) -> None:
        if self.baseline is not None:
            validate.positive(self.baseline, "--baseline", "m", cap=2.0)
        validate.positive(self.baseline_tolerance, "--baseline-tolerance", "m", cap=1.0)
        for name in ("base_frame", "flange_frame"):
            if not getattr(self, name).strip():
                raise ConfigError(f"--{name.replace('_', '-')} is empty")


def camera_info_topic(image_topic: str) -> str:
    """image_transport's rule: ``camera_info`` beside the image (``/cam/image_raw`` and
    ``/cam/image_raw/compressed`` -> ``/cam/camera_info``)."""
    base = image_topic.removesuffix("/compressed").rstrip("/")
    return (base.rsplit("/", 1)[0] if "/" in base else "") + "/camera_info"


def import_bag(bag_path: str | Path, out: str | Path, options: ImportOptions) -> dict:
    """Import ``bag_path`` into the recording ``out`` (and the calibration recording); returns
    the report. ConfigError for bad arguments or absent topics, RecordingError for a bag that
    cannot give views (broken TF, stamps out of order, no camera at rest)."""
    out = Path(out)
    model = _model(options)
    with BagReader(bag_path) as bag:
        topics = _topics(bag, options)
        contents = collect(bag, topics, model.joint_names if model else JOINT_NAMES)
        if not contents.images:
            raise RecordingError(f"{topics.image} in {bag.path.name} holds no usable image")
        if not contents.camera_infos:
            raise RecordingError(f"{topics.camera_info} in {bag.path.name} holds no usable "
                                 "camera info (plumb_bob or rational_polynomial, full sensor)")
        camera = options.camera_frame or _image_frame(contents, topics.image)
        poses = _pose_source(contents, options, camera, model, topics)
        views, pairs, notes = (_from_events(contents) if contents.events and options.use_events
                               else _at_rest(contents, poses, options))
        if not views:
            raise RecordingError(_no_view_reason(contents, poses, options, camera))
        records = _records(bag, topics, contents, poses, views, options)
        problems = bag.problems() + notes
    metadata = _metadata(bag, options, topics, poses.name, camera, model, contents)
    session = _calibration_session(out, records, metadata, options, model)
    write_recording(out, records, pairs, metadata, calibration_ns=_calibration_time(contents))
    if session is not None:
        path, seen, meta = session
        write_recording(path, seen, [], meta)
    report = {"bag": str(bag_path), "out": str(out), "pose_source": poses.name,
              "camera_frame": camera, "views": len(records), "pairs": [
                  {"pair": p[0], "left_view": p[1], "right_view": p[2],
                   "achieved_baseline_m": p[4], "direction": p[5]} for p in pairs],
              "from_events": bool(contents.events and options.use_events),
              "calibration": None, "warnings": problems}
    if options.board is not None:
        report["calibration"] = ({"out": str(session[0]), "views": len(session[1])}
                                 if session else {"out": None, "views": 0})
    return report


def _model(options: ImportOptions) -> ArmModel | None:
    if options.robot is None:
        return None
    from armstereo.robot.model_file import load_arm_model

    return load_arm_model(options.robot, mount=CameraMount.load(options.mount))


def _topics(bag: BagReader, options: ImportOptions) -> Topics:
    bag.require(options.image_topic, R.IMAGE_TYPES, "image")
    info = options.camera_info_topic or camera_info_topic(options.image_topic)
    if options.camera_info_topic is None and info not in bag.topics:
        found = bag.topics_of_type([R.CAMERA_INFO])
        if len(found) == 1:
            log.info("using %s as the camera info of %s", found[0], options.image_topic)
            info = found[0]
    bag.require(info, [R.CAMERA_INFO], "camera info")

    def optional(topic: str, types: list[str]) -> str | None:
        if topic not in bag.topics:
            return None
        bag.require(topic, types, topic)
        return topic

    return Topics(image=options.image_topic, camera_info=info,
                  tf=optional(options.tf_topic, [R.TF_MESSAGE]),
                  tf_static=optional(options.tf_static_topic, [R.TF_MESSAGE]),
                  joint_states=optional(options.joint_states_topic, [R.JOINT_STATE]),
                  events=optional(EVENTS_TOPIC, [R.STRING]) if options.use_events else None,
                  depth=optional(DEPTH_TOPIC, [R.IMAGE]) if options.use_events else None)


def _image_frame(c: Contents, topic: str) -> str:
    frames = {im.frame_id for im in c.images}
    if len(frames) != 1 or not next(iter(frames)):
        raise RecordingError(f"the images on {topic} name {len(frames)} frame ids "
                             f"({', '.join(sorted(frames)) or 'empty'}); give --camera-frame")
    return frames.pop()


def _pose_source(c: Contents, options: ImportOptions, camera: str, model: ArmModel | None,
                 topics: Topics):
    base, flange = options.base_frame, options.flange_frame
    problem = c.tf.chain_problem(base, flange) or c.tf.chain_problem(flange, camera)
    if problem is None:
        return TfPoses(c.tf, base, flange, camera)
    if model is None or c.joints is None or not len(c.joints):
        hint = (f"; or give --robot with the arm's joint states on {options.joint_states_topic}"
                if model is None else f"; and {options.joint_states_topic} has no joint states "
                "of the arm")
        raise RecordingError(f"{problem}{hint}")
    T_fc = model.mount.T_flange_camera
    if c.tf.chain_problem(flange, camera) is None:  # the camera's TF, without the arm's
        stamps = np.array([im.stamp_ns for im in c.images[:1]])
        T, ok = c.tf.lookup(flange, camera, stamps)
        T_fc = T[0] if ok[0] else T_fc
    log.info("camera poses from %s through %s's kinematics (%s)", topics.joint_states,
             model.name, problem)
    return JointPoses(c.joints, model, T_fc)


def _at_rest(c: Contents, poses, options: ImportOptions):
    stamps = np.array([im.stamp_ns for im in c.images], dtype=np.int64)
    still = still_mask(stamps, poses, options.rest)
    T_bf, T_fc, _ = poses.at(stamps)
    T_cam = T_bf @ T_fc
    chosen = rest_views(stamps, T_cam, still, options.rest)
    views = [{"view": k, "image": c.images[i], "settle_s": float(settle), "controller": None}
             for k, (i, settle) in enumerate(chosen)]
    intr = [c.intrinsics_at(v["image"].stamp_ns) for v in views]
    choices, notes = choose_pairs([T_cam[i] for i, _ in chosen], intr, options.baseline,
                                  options.baseline_tolerance)
    pairs = [(n, p.left, p.right, options.baseline if options.baseline else p.achieved_m,
              p.achieved_m, p.direction, None) for n, p in enumerate(choices)]
    return views, pairs, notes


def _from_events(c: Contents):
    by_stamp = {im.stamp_ns: im for im in c.images}
    views, notes = [], []
    for e in (e for e in c.events if e["event"] == "view"):
        im = by_stamp.get(int(e["timestamp_ns"]))
        if im is None:
            notes.append(f"view {e['view']}: no image stamped {e['timestamp_ns']} ns; skipped")
            continue
        pose = e.get("controller_T_base_tool0")
        views.append({"view": int(e["view"]), "image": im, "settle_s": float(e["settle_s"]),
                      "controller": None if pose is None
                      else np.asarray(pose, dtype=float).reshape(4, 4)})
    have = {v["view"] for v in views}
    pairs = [(int(e["pair"]), int(e["left_view"]), int(e["right_view"]),
              float(e["commanded_baseline_m"]), float(e["achieved_baseline_m"]),
              str(e["direction"]), e.get("viewpoint"))
             for e in c.events if e["event"] == "pair"
             and {e["left_view"], e["right_view"]} <= have]
    return views, pairs, notes


def _no_view_reason(c: Contents, poses, options: ImportOptions, camera: str) -> str:
    stamps = [im.stamp_ns for im in c.images]
    if isinstance(poses, TfPoses):
        span = c.tf.coverage(options.base_frame, camera)
        if span is None or span[1] < stamps[0] or span[0] > stamps[-1]:
            return (f"the TF from {options.base_frame} to {camera} does not cover the images' "
                    f"stamps ({stamps[0]}..{stamps[-1]} ns): are the images and /tf on one "
                    "clock?")
    return (f"none of the {len(stamps)} images was taken while the camera was at rest (still "
            f"within {options.rest.still_m * 1000:g} mm and {options.rest.still_deg:g} deg for "
            f"{options.rest.window_s:g} s); see --still-window, --still-tolerance")


def _records(bag: BagReader, topics: Topics, c: Contents, poses, views: list[dict],
             options: ImportOptions) -> list[ViewRecord]:
    refs = [v["image"] for v in views]
    intr = {im.number: c.intrinsics_at(im.stamp_ns) for im in refs}
    images = load_images(bag, topics.image, intr)
    depth_numbers = {c.depth_stamps[im.stamp_ns]: im.stamp_ns for im in refs
                     if im.stamp_ns in c.depth_stamps}
    depth = load_depth(bag, topics.depth, depth_numbers) if depth_numbers else {}
    depth_at = {depth_numbers[n]: d for n, d in depth.items()}
    stamps = np.array([im.stamp_ns for im in refs], dtype=np.int64)
    T_bf, T_fc, valid = poses.at(stamps)
    q, q_ok = (c.joints.at(stamps) if c.joints is not None and len(c.joints)
               else (None, np.zeros(len(refs), bool)))
    out = []
    for k, (v, im) in enumerate(zip(views, refs, strict=True)):
        if not valid[k] or im.number not in images:
            raise RecordingError(f"view {v['view']} (image stamped {im.stamp_ns} ns) has no "
                                 f"pose or image")
        out.append(ViewRecord(
            index=v["view"], stamp_ns=im.stamp_ns, image=images[im.number],
            intrinsics=intr[im.number], T_base_flange=T_bf[k], T_flange_camera=T_fc[k],
            joints=q[k] if q_ok[k] else None, settle_s=v["settle_s"],
            controller_T_base_flange=v["controller"], depth=depth_at.get(im.stamp_ns),
            sees_board=options.board is not None
            and _sees_board(images[im.number], options.board)))
    return out


def _sees_board(image: np.ndarray, board: Board) -> bool:
    try:
        return detect_board(image, board) is not None
    except cv2.error:  # OpenCV's chessboard finder fails on very small images: no board
        return False


def _calibration_time(c: Contents) -> int | None:
    """The first camera info's stamp when it precedes the images (an armstereo export logs
    the calibration before the first view), else None (just before the first view)."""
    first = min(t for t, _, _ in c.camera_infos)
    return first if first < c.images[0].stamp_ns else None


def _metadata(bag: BagReader, options: ImportOptions, topics: Topics, source: str,
              camera: str, model: ArmModel | None, c: Contents) -> dict[str, str]:
    meta: dict[str, str] = {}
    if c.events and options.use_events:  # an armstereo export: its recording's metadata
        meta = {k.removeprefix(CUSTOM_PREFIX): v for k, v in bag.custom_data.items()
                if k.startswith(CUSTOM_PREFIX)
                and k.removeprefix(CUSTOM_PREFIX) not in _NOT_RESTORED}
    meta.update({"imported_from": "ros2", "ros2_bag": bag.path.name,
                 "image_topic": topics.image, "camera_info_topic": topics.camera_info,
                 "pose_source": source, "base_frame": options.base_frame,
                 "flange_frame": options.flange_frame, "camera_frame": camera})
    if model is not None:
        meta.setdefault("robot", model.name)
        meta.setdefault("urdf_sha256", model.urdf_sha256)
        if source == "joints":
            from armstereo.capture.run import model_metadata

            meta.update({k: v for k, v in model_metadata(model).items()
                         if k != "armstereo_version"})
    if options.mount is not None:
        meta["mount_toml"] = model.mount.source if model else CameraMount.load(
            options.mount).source
    return meta


def _calibration_session(out: Path, records: list[ViewRecord], metadata: dict[str, str],
                         options: ImportOptions, model: ArmModel | None):
    """(path, views, metadata) of the calibration recording, None if no view sees the board;
    ConfigError/RecordingError, before anything is written, when it cannot be made."""
    seen = [r for r in records if r.sees_board]
    if options.board is None or not seen:
        return None
    if "robot" not in metadata:
        raise ConfigError(f"{len(seen)} view(s) see the board, but the calibration recording "
                          "needs the arm model its flange poses are computed with: give --robot")
    missing = [r.index for r in seen if r.joints is None]
    if missing:
        raise RecordingError(f"views {missing} see the board but have no joint states; "
                             "calibration needs the arm's joints")
    meta = {k: v for k, v in metadata.items() if k not in ("pairs", "kind")}
    meta.update(calibration_metadata(options.board, len(seen)))
    if "mount_toml" not in meta and model is not None:
        meta["mount_toml"] = model.mount.source
    path = options.calibration_out or out.with_name(f"{out.stem}_calibration.mcap")
    return path, seen, meta
