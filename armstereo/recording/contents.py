"""What a recording holds: views, pairs, channels and point clouds, and the
:class:`RecordingContents` the scan (:mod:`~armstereo.recording.mcap_scan`) and the assembly
(:mod:`~armstereo.recording.assemble`) fill in, which :class:`~armstereo.recording.reader.Recording`
opens and gives access to. Defined here, below all three, so none imports the reader back."""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path

import numpy as np
from foxglove_schemas_protobuf.RawImage_pb2 import RawImage

from armstereo.camera_model import Intrinsics
from armstereo.recording.decode import decode_depth, decode_image


@dataclass(eq=False)
class View:
    """One recorded view: image, poses (``base`` frame, metres), intrinsics, joints.

    ``image`` (uint8, BGR or grey) and ``depth`` (float32 metres, NaN = none, or None) are
    decoded on first access and raise :class:`RecordingError` if the stored bytes are bad.
    """

    index: int
    timestamp_ns: int
    T_base_flange: np.ndarray
    T_flange_camera: np.ndarray
    intrinsics: Intrinsics | None
    joint_names: tuple[str, ...] = ()
    joint_positions: np.ndarray | None = None
    settle_s: float | None = None
    image_format: str = "png"
    image_size: tuple[int, int] | None = None  # (width, height) from the image header
    # The controller's own T_base_flange at this view's joints (if the arm reported one).
    controller_T_base_flange: np.ndarray | None = None
    _image_data: bytes = field(default=b"", repr=False)
    _depth_msg: RawImage | None = field(default=None, repr=False)

    @property
    def T_base_camera(self) -> np.ndarray:
        """Pose of ``camera_optical`` in ``base``: ``T_base_flange @ T_flange_camera``."""
        return self.T_base_flange @ self.T_flange_camera

    @property
    def has_depth(self) -> bool:
        return self._depth_msg is not None

    @cached_property
    def image(self) -> np.ndarray:
        return decode_image(self._image_data, self.image_format, self.intrinsics,
                             f"view {self.index}")

    @cached_property
    def depth(self) -> np.ndarray | None:
        if self._depth_msg is None:
            return None
        return decode_depth(self._depth_msg, self.intrinsics, f"view {self.index}")


@dataclass(frozen=True, eq=False)
class Pair:
    """Two views that form a stereo pair, with the baselines the capture reported (metres) and
    the scan viewpoint it was shot from (None outside a scan)."""

    index: int
    left: View
    right: View
    commanded_baseline_m: float
    achieved_baseline_m: float
    direction: str
    viewpoint: int | None = None


@dataclass(frozen=True)
class ChannelInfo:
    """A channel and the number of its messages that were read."""

    topic: str
    schema: str
    encoding: str
    messages: int



@dataclass(frozen=True)
class RecordedPointCloud:
    """A point cloud read from the file: points (N, 3) metres in ``frame_id``, BGR colours."""

    timestamp_ns: int
    frame_id: str
    topic: str
    points: np.ndarray
    colors_bgr: np.ndarray


class RecordingContents:
    """What was read from one file: filled in by the scan and the assembly, read through
    :class:`~armstereo.recording.reader.Recording`."""

    def __init__(self, path: Path, size_bytes: int) -> None:
        self.path = path
        self.size_bytes = size_bytes
        self.indexed = False
        self.truncated = False
        self.lost: list[str] = []  # what could not be read, one line each
        self.warnings: list[str] = []  # every problem found, including the lost items
        self.metadata: dict[str, str] = {}
        self.metadata_records: dict[str, dict[str, str]] = {}
        self.channels: list[ChannelInfo] = []
        self.views: list[View] = []
        self.pair_events: list[dict] = []  # as recorded, complete or not
        self.calibration: Intrinsics | None = None
        self.calibration_info: dict | None = None  # frame_id, distortion_model, ...
        self.point_clouds: list[RecordedPointCloud] = []
        self.start_ns: int | None = None
        self.end_ns: int | None = None
        self._pairs: list[Pair] = []

    def _warn(self, text: str) -> None:
        self.warnings.append(text)

    def _lose(self, text: str) -> None:
        self.lost.append(text)
        self.warnings.append(text)
