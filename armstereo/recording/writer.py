"""Write capture recordings (MCAP) that survive being killed at any moment.

Each public ``write_*`` call ends with a flush: the open chunk is closed and written, so a
process killed even by SIGKILL leaves a file that a streaming reader reads up to the last
complete call (in particular the last complete view). In the main thread, SIGINT and SIGTERM are
held back while a call writes and delivered right after it, so Ctrl-C never lands inside the
MCAP writer and ``close()`` (from a ``finally`` or ``with``) always finishes a valid file.

The messages' contents are built in :mod:`~armstereo.recording.messages`, the file lock and the
signal hold-back are in :mod:`~armstereo.recording.crash_safe`.
"""

from __future__ import annotations

import contextlib
import json
import logging
import os
from collections.abc import Iterator, Mapping, Sequence
from pathlib import Path

import cv2
import numpy as np
from foxglove_schemas_protobuf.CameraCalibration_pb2 import CameraCalibration
from foxglove_schemas_protobuf.CompressedImage_pb2 import CompressedImage
from foxglove_schemas_protobuf.PointCloud_pb2 import PointCloud
from foxglove_schemas_protobuf.Pose_pb2 import Pose
from foxglove_schemas_protobuf.Quaternion_pb2 import Quaternion
from foxglove_schemas_protobuf.Vector3_pb2 import Vector3
from google.protobuf.message import Message
from mcap.writer import LIBRARY_IDENTIFIER, CompressionType
from mcap.writer import Writer as McapWriter
from mcap_protobuf.schema import register_schema

from armstereo import __version__
from armstereo.camera_model import Intrinsics
from armstereo.errors import ConfigError, RecordingError
from armstereo.frame import Frame
from armstereo.recording import schemas as S
from armstereo.recording.crash_safe import open_exclusive, signals_deferred
from armstereo.recording.messages import (
    POINT_DTYPE,
    POINT_STRIDE,
    check_index,
    check_number,
    check_time,
    check_vector,
    depth_message,
    frames_message,
    point_fields,
    stamp,
)
from armstereo.transforms import as_rigid

log = logging.getLogger(__name__)

CHUNK_SIZE = 256 * 1024  # bytes; every write_* call also closes its chunk (crash safety)
# Chunk compression: PNG/JPEG payloads do not shrink further; on the raw float32 ground-truth
# depth zstd stores ~40 % less than LZ4 for ~1 ms per view (see bench/record.py).
CHUNK_COMPRESSION = CompressionType.ZSTD
# PNG: zlib's run-length strategy with the "average" row filter encodes a textured 640x480
# view about twice as fast as OpenCV's explicit level 1 (default strategy, adaptive filters) and
# slightly smaller (see bench/record.py). Filter selection needs OpenCV >= 4.10.
PNG_PARAMS: tuple[int, ...] = (
    cv2.IMWRITE_PNG_COMPRESSION, 1, cv2.IMWRITE_PNG_STRATEGY, cv2.IMWRITE_PNG_STRATEGY_RLE,
    *((cv2.IMWRITE_PNG_FILTER, cv2.IMWRITE_PNG_FILTER_AVG)
      if hasattr(cv2, "IMWRITE_PNG_FILTER") else ()),
)
JPEG_QUALITY = 95


class RecordingWriter:
    """Typed writer for armstereo recordings (see ``armstereo.recording.schemas``).

    ``metadata`` (str -> str) is stored at once in the MCAP metadata record ``armstereo`` with
    ``format_version`` and ``armstereo_version`` added. ``image_format`` is ``png`` (lossless,
    default) or ``jpeg``. ``fsync=True`` also forces each flush to disk (power-loss safety; a
    killed process loses nothing already flushed even without it). ``png_params`` (OpenCV
    ``imwrite`` flags), ``jpeg_quality`` and ``chunk_compression`` trade speed for size; the
    defaults record 640x480 views well above 30/s. Raises :class:`RecordingError`
    when the file cannot be written or a value is malformed; a call that raises wrote nothing.
    """

    def __init__(self, path: str | Path, *, metadata: Mapping[str, str],
                 image_format: str = "png", fsync: bool = False,
                 png_params: Sequence[int] = PNG_PARAMS, jpeg_quality: int = JPEG_QUALITY,
                 chunk_compression: CompressionType = CHUNK_COMPRESSION) -> None:
        if image_format not in S.IMAGE_FORMATS:
            raise ConfigError(f"image format must be one of {', '.join(S.IMAGE_FORMATS)}, "
                              f"not {image_format!r}")
        record = _metadata_record(metadata)
        self.path = Path(path)
        self.image_format = image_format
        self._fsync = fsync
        self._encode_params = ([int(p) for p in png_params] if image_format == "png"
                               else [cv2.IMWRITE_JPEG_QUALITY, int(jpeg_quality)])
        self._schema_ids: dict[str, int] = {}
        self._channel_ids: dict[str, tuple[int, str]] = {}  # topic -> (channel id, schema)
        self._sequence: dict[str, int] = {}
        self._view_times: dict[int, int] = {}
        self._calibration_size: tuple[int, int] | None = None
        self._closed = False
        self._broken = False  # a write failed half way: close() must not trust the writer
        self._good_offset = 0  # file size after the last complete flush
        self._file = open_exclusive(self.path)  # closed by close()
        try:
            self._mcap = McapWriter(self._file, chunk_size=CHUNK_SIZE,
                                    compression=chunk_compression)
            library = f"armstereo {__version__} ({LIBRARY_IDENTIFIER})"
            with self._operation():
                self._mcap.start(profile="", library=library)  # protobuf is no ROS profile
                self._mcap.add_metadata(S.METADATA_NAME, record)
        except BaseException:
            self._closed = True
            self._file.close()
            raise

    # ----------------------------------------------------------------- context manager, state
    def __enter__(self) -> RecordingWriter:
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        if exc_type is None:
            self.close()
            return
        try:
            self.close()
        except RecordingError as err:  # keep the original error; this one is secondary
            log.error("%s", err)

    @property
    def closed(self) -> bool:
        return self._closed

    @property
    def views_written(self) -> int:
        """Number of complete views in the file (each one flushed)."""
        return len(self._view_times)

    # ----------------------------------------------------------------------------- high level
    def write_calibration(self, intrinsics: Intrinsics, t_ns: int,
                          frame_id: str = S.FRAME_CAMERA) -> None:
        """Record the camera intrinsics (``foxglove.CameraCalibration``, R = I, P = [K|0])."""
        t_ns = check_time(t_ns)
        K = np.asarray(intrinsics.K, dtype=float)
        D = np.asarray(intrinsics.dist, dtype=float).reshape(-1)
        if D.size == 4:
            D = np.append(D, 0.0)  # Foxglove's plumb_bob has 5 terms; k3 = 0 is the same model
        model = S.DISTORTION_PLUMB_BOB if D.size == 5 else S.DISTORTION_RATIONAL
        P = np.hstack([K, np.zeros((3, 1))])
        msg = CameraCalibration(timestamp=stamp(t_ns), frame_id=frame_id,
                                width=int(intrinsics.width), height=int(intrinsics.height),
                                distortion_model=model, D=D.tolist(), K=K.reshape(-1).tolist(),
                                R=np.eye(3).reshape(-1).tolist(), P=P.reshape(-1).tolist())
        with self._operation():
            self._add(S.TOPIC_CALIBRATION, t_ns, msg)
            self._calibration_size = (msg.width, msg.height)

    def write_view(self, view: int, frame: Frame, q: np.ndarray, joint_names: Sequence[str],
                   T_base_flange: np.ndarray, T_flange_camera: np.ndarray, *,
                   settle_s: float, controller_T_base_flange: np.ndarray | None = None) -> None:
        """Record one view: image, ground-truth depth (if any), /tf, joint states, view event.

        ``q`` are the actual joints (rad) at exposure, ``T_base_flange`` their forward
        kinematics and ``T_flange_camera`` the mount; all share ``frame.timestamp_ns``.
        ``controller_T_base_flange``: the flange pose the arm's controller reported for the same
        joints (kept in the view event, for the FK cross-check), if the arm reports one.
        """
        view = check_index("view", view)
        t_ns = check_time(frame.timestamp_ns)
        if view in self._view_times:
            raise RecordingError(f"view {view} was already written to {self.path}")
        for other, t_other in self._view_times.items():
            if t_other == t_ns:
                raise RecordingError(f"view {view} has the same timestamp {t_ns} ns as view "
                                     f"{other}; camera timestamps must differ between views")
        q = check_vector("joint positions", q)
        names = [str(n) for n in joint_names]
        if len(names) != q.size:
            raise RecordingError(f"{q.size} joint positions but {len(names)} joint names")
        size = np.shape(frame.image)[1::-1]
        if self._calibration_size is not None and size != self._calibration_size:
            raise RecordingError(f"view {view} image is {size[0]}x{size[1]} but the calibration "
                                 f"says {self._calibration_size[0]}x{self._calibration_size[1]}")
        if frame.depth is not None and np.shape(frame.depth) != np.shape(frame.image)[:2]:
            raise RecordingError(f"view {view} depth is {np.shape(frame.depth)}, its image "
                                 f"{np.shape(frame.image)[:2]}")
        image_msg = self._image_message(frame.image, t_ns, S.FRAME_CAMERA)
        depth_msg = None if frame.depth is None else depth_message(frame.depth, t_ns,
                                                                    S.FRAME_CAMERA)
        tf_msg = frames_message(T_base_flange, T_flange_camera, t_ns)
        joints = {"timestamp_ns": t_ns, "view": view, "names": names, "positions": q.tolist()}
        event = {"event": "view", "view": view, "timestamp_ns": t_ns,
                 "settle_s": check_number("settle_s", settle_s)}
        if controller_T_base_flange is not None:
            event["controller_T_base_tool0"] = as_rigid(
                controller_T_base_flange, "controller T_base_flange",
                error=RecordingError).reshape(-1).tolist()
        with self._operation():
            self._add(S.TOPIC_IMAGE, t_ns, image_msg)
            if depth_msg is not None:
                self._add(S.TOPIC_DEPTH, t_ns, depth_msg)
            self._add(S.TOPIC_TF, t_ns, tf_msg)
            self._add(S.TOPIC_JOINT_STATES, t_ns, joints)
            self._add(S.TOPIC_EVENTS, t_ns, event)  # last: marks the view complete
            self._view_times[view] = t_ns

    def write_pair(self, pair: int, left_view: int, right_view: int,
                   commanded_baseline_m: float, achieved_baseline_m: float,
                   direction: str, *, viewpoint: int | None = None) -> None:
        """Record that two written views form stereo pair ``pair`` (logged at the later view).
        ``viewpoint``: the scan viewpoint the pair was shot from (``armstereo scan``; the
        event then carries it), None for a single-line capture."""
        pair = check_index("pair", pair)
        for name, v in (("left_view", left_view), ("right_view", right_view)):
            if v not in self._view_times:
                raise RecordingError(f"pair {pair}: {name} {v} was not written to {self.path}")
        t_ns = max(self._view_times[left_view], self._view_times[right_view])
        commanded = check_number("commanded baseline", commanded_baseline_m)
        achieved = check_number("achieved baseline", achieved_baseline_m)
        event = {"event": "pair", "pair": pair, "left_view": int(left_view),
                 "right_view": int(right_view), "commanded_baseline_m": commanded,
                 "achieved_baseline_m": achieved, "direction": str(direction)}
        if viewpoint is not None:
            event["viewpoint"] = check_index("viewpoint", viewpoint)
        with self._operation():
            self._add(S.TOPIC_EVENTS, t_ns, event)

    def write_point_cloud(self, points_base: np.ndarray, colors_bgr: np.ndarray, t_ns: int,
                          frame_id: str = S.FRAME_BASE, topic: str = S.TOPIC_POINTS) -> None:
        """Record a coloured point cloud (``foxglove.PointCloud``, float32 xyz + rgba, metres)."""
        t_ns = check_time(t_ns)
        pts = np.asarray(points_base, dtype=float)
        cols = np.asarray(colors_bgr)
        if pts.ndim != 2 or pts.shape[1] != 3:
            raise RecordingError(f"points must be (N, 3), got shape {pts.shape}")
        if cols.shape != pts.shape or cols.dtype != np.uint8:
            raise RecordingError(f"colours must be uint8 {pts.shape}, got {cols.dtype} "
                                 f"{cols.shape}")
        packed = np.empty(len(pts), dtype=POINT_DTYPE)
        for axis, name in enumerate("xyz"):
            packed[name] = pts[:, axis]
        packed["red"], packed["green"], packed["blue"] = cols[:, 2], cols[:, 1], cols[:, 0]
        packed["alpha"] = 255
        msg = PointCloud(timestamp=stamp(t_ns), frame_id=frame_id,
                         pose=Pose(position=Vector3(), orientation=Quaternion(w=1.0)),
                         point_stride=POINT_STRIDE, fields=point_fields(),
                         data=packed.tobytes())
        self._check_topic(topic, msg)
        with self._operation():
            self._add(topic, t_ns, msg)

    # ------------------------------------------------------------------------------ low level
    def write_image(self, topic: str, image: np.ndarray, t_ns: int,
                    frame_id: str = S.FRAME_CAMERA) -> None:
        """Record a uint8 BGR or grey image on ``topic`` as ``foxglove.CompressedImage``."""
        t_ns = check_time(t_ns)
        msg = self._image_message(image, t_ns, frame_id)
        self._check_topic(topic, msg)
        with self._operation():
            self._add(topic, t_ns, msg)

    def write_depth(self, depth: np.ndarray, t_ns: int, frame_id: str = S.FRAME_CAMERA,
                    topic: str = S.TOPIC_DEPTH) -> None:
        """Record a float32 depth image (metres, NaN = none) as ``foxglove.RawImage`` 32FC1."""
        t_ns = check_time(t_ns)
        msg = depth_message(depth, t_ns, frame_id)
        self._check_topic(topic, msg)
        with self._operation():
            self._add(topic, t_ns, msg)

    def write_frames(self, T_base_flange: np.ndarray, T_flange_camera: np.ndarray,
                     t_ns: int) -> None:
        """Record base -> tool0 and tool0 -> camera_optical on /tf (``FrameTransforms``)."""
        t_ns = check_time(t_ns)
        msg = frames_message(T_base_flange, T_flange_camera, t_ns)
        with self._operation():
            self._add(S.TOPIC_TF, t_ns, msg)

    def flush(self) -> None:
        """Write everything buffered to the file (each ``write_*`` call already does)."""
        with self._operation():
            pass

    def close(self) -> None:
        """Finish the file (summary and index) and close it; safe to call more than once.

        If an earlier call failed half way (e.g. the disk filled up), the file is cut back to
        its last complete flush instead, which streaming readers read in full.
        """
        if self._closed:
            return
        self._closed = True
        failure = None
        with signals_deferred():
            try:
                if not self._broken:
                    self._mcap.finish()
                    self._file.flush()
                    if self._fsync:
                        os.fsync(self._file.fileno())
            except OSError as err:
                self._broken, failure = True, err
            finally:
                with contextlib.suppress(OSError):  # the failure that matters is reported
                    self._file.close()
            if self._broken:
                self._cut_back()
        if failure is not None:
            raise RecordingError(f"finishing recording {self.path} failed: {failure}")

    def _cut_back(self) -> None:
        """Drop whatever follows the last complete flush (a half-written record)."""
        try:
            os.truncate(self.path, self._good_offset)
        except OSError as err:
            log.error("could not cut %s back to %d bytes: %s", self.path, self._good_offset, err)
            return
        log.warning("recording %s was cut back to its last complete flush; it has no index but "
                    "reads by streaming", self.path)

    # ------------------------------------------------------------------------------ internals
    @contextlib.contextmanager
    def _operation(self) -> Iterator[None]:
        """One public write: no signal inside, flushed at the end, errors as RecordingError."""
        if self._closed:
            raise RecordingError(f"recording {self.path} is already closed")
        if self._broken:
            raise RecordingError(f"recording {self.path} failed earlier and takes no more data")
        with signals_deferred():
            try:
                yield
                self._mcap.flush()
                if self._fsync:
                    os.fsync(self._file.fileno())
                self._good_offset = self._file.tell()
            except BaseException as err:
                self._broken = True
                if isinstance(err, OSError):
                    raise RecordingError(f"writing {self.path} failed: {err}") from None
                raise

    def _check_topic(self, topic: str, msg: Message) -> None:
        """A topic carries one schema: the documented one, or the one it was first used with."""
        name = msg.DESCRIPTOR.full_name
        known = self._channel_ids[topic][1] if topic in self._channel_ids else \
            S.EXPECTED_SCHEMAS.get(topic, (name,))[0]
        if known != name:
            raise RecordingError(f"topic {topic} carries {known}, not {name}")

    def _add(self, topic: str, t_ns: int, msg: Message | dict) -> None:
        """Append one message (protobuf, or a dict for the JSON topics) to the open chunk."""
        if isinstance(msg, dict):
            name, schema = S.JSON_SCHEMAS[topic]
            payload = json.dumps(msg, separators=(",", ":"), allow_nan=False).encode()
            channel = self._channel(topic, name, S.JSON, lambda: self._mcap.register_schema(
                name=name, encoding=S.JSONSCHEMA, data=S.json_schema_bytes(schema)))
        else:
            name, payload = msg.DESCRIPTOR.full_name, msg.SerializeToString()
            channel = self._channel(topic, name, S.PROTOBUF,
                                    lambda: register_schema(self._mcap, type(msg)))
        seq = self._sequence.get(topic, 0)
        self._sequence[topic] = seq + 1
        self._mcap.add_message(channel_id=channel, log_time=t_ns, publish_time=t_ns,
                               data=payload, sequence=seq & 0xFFFFFFFF)

    def _channel(self, topic: str, schema_name: str, encoding: str, register) -> int:
        if topic not in self._channel_ids:
            if schema_name not in self._schema_ids:
                self._schema_ids[schema_name] = register()
            cid = self._mcap.register_channel(topic=topic, message_encoding=encoding,
                                              schema_id=self._schema_ids[schema_name])
            self._channel_ids[topic] = (cid, schema_name)
        return self._channel_ids[topic][0]

    def _image_message(self, image: np.ndarray, t_ns: int, frame_id: str) -> CompressedImage:
        img = np.asarray(image)
        if img.ndim == 3 and img.shape[2] == 1:
            img = img[:, :, 0]
        if img.dtype != np.uint8 or not (img.ndim == 2 or (img.ndim == 3 and img.shape[2] == 3)):
            raise RecordingError(f"image must be uint8 HxW or HxWx3 (BGR), got {img.dtype} "
                                 f"{img.shape}")
        ext = ".png" if self.image_format == "png" else ".jpg"
        ok, buf = cv2.imencode(ext, img, self._encode_params)
        if not ok:
            raise RecordingError(f"OpenCV could not encode a {img.shape} image as "
                                 f"{self.image_format}")
        return CompressedImage(timestamp=stamp(t_ns), frame_id=frame_id,
                               format=self.image_format, data=buf.tobytes())


def _metadata_record(metadata: Mapping[str, str]) -> dict[str, str]:
    record = {"format_version": S.FORMAT_VERSION, "armstereo_version": __version__}
    for key, value in metadata.items():
        if not isinstance(key, str) or not isinstance(value, str):
            raise RecordingError(f"metadata must map str to str; {key!r} -> "
                                 f"{type(value).__name__} {value!r}")
        record[key] = value
    return record
