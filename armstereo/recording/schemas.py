"""The recording format: topics, schemas, encodings and frame ids as named constants.

Every channel uses a published ``foxglove.*`` protobuf schema except the two armstereo JSON
channels (joint states and capture events), whose JSON Schemas are defined here. All messages of
one view share one timestamp: ``log_time == publish_time ==`` the exposure time of the view's
image in integer nanoseconds; the view event ties the view's number to that time.
"""

from __future__ import annotations

import json

from foxglove_schemas_protobuf.CameraCalibration_pb2 import CameraCalibration
from foxglove_schemas_protobuf.CompressedImage_pb2 import CompressedImage
from foxglove_schemas_protobuf.FrameTransforms_pb2 import FrameTransforms
from foxglove_schemas_protobuf.PointCloud_pb2 import PointCloud
from foxglove_schemas_protobuf.RawImage_pb2 import RawImage
from mcap.well_known import MessageEncoding, SchemaEncoding

FORMAT_VERSION = "1"  # stored in the metadata record; bump when a reader must tell formats apart
METADATA_NAME = "armstereo"

# Frame ids (see docs: `base` is the UR controller's base frame, `tool0` the flange).
FRAME_BASE = "base"
FRAME_FLANGE = "tool0"
FRAME_CAMERA = "camera_optical"

# Topics: keep these names stable, Foxglove layouts and offline tools refer to them.
TOPIC_IMAGE = "/camera/image"
TOPIC_CALIBRATION = "/camera/calibration"
TOPIC_TF = "/tf"
TOPIC_JOINT_STATES = "/joint_states"
TOPIC_EVENTS = "/capture/events"
TOPIC_DEPTH = "/camera/depth_truth"
TOPIC_POINTS = "/points"

# Derived data (rectified images, disparity, estimated depth, ...) that reconstruction writes
# beside the recorded topics: listed by inspect, skipped by the reader without a warning.
DERIVED_TOPIC_PREFIX = "/reconstruction/"
TOPIC_DEPTH_ESTIMATE = "/reconstruction/depth"  # float32 m, original left view (camera_optical)
TOPIC_RECTIFIED_LEFT = "/reconstruction/rectified_left"
TOPIC_RECTIFIED_RIGHT = "/reconstruction/rectified_right"
TOPIC_DISPARITY = "/reconstruction/disparity"  # colorized, rectified left view
FRAME_RECTIFIED_LEFT = "camera_rectified_left"

PROTOBUF = MessageEncoding.Protobuf  # message and schema encoding of the foxglove channels
JSON = MessageEncoding.JSON
JSONSCHEMA = SchemaEncoding.JSONSchema

# Image formats a CompressedImage may carry (Foxglove's `format` field).
IMAGE_FORMATS = ("png", "jpeg")
DEPTH_ENCODING = "32FC1"  # float32 metres, little endian, NaN = no depth

# Foxglove's names for OpenCV's distortion vectors.
DISTORTION_PLUMB_BOB = "plumb_bob"  # k1, k2, p1, p2, k3
DISTORTION_RATIONAL = "rational_polynomial"  # k1, k2, p1, p2, k3, k4, k5, k6 (+ OpenCV extras)

JOINT_STATES_SCHEMA_NAME = "armstereo.JointStates"
CAPTURE_EVENT_SCHEMA_NAME = "armstereo.CaptureEvent"

JOINT_STATES_SCHEMA = {
    "$schema": "https://json-schema.org/draft/2020-12/schema",
    "title": JOINT_STATES_SCHEMA_NAME,
    "description": "Actual joint positions of the arm when a view was shot (radians).",
    "type": "object",
    "properties": {
        "timestamp_ns": {"type": "integer", "description": "exposure time of the view, ns"},
        "view": {"type": "integer", "minimum": 0},
        "names": {"type": "array", "items": {"type": "string"}},
        "positions": {"type": "array", "items": {"type": "number"}},
    },
    "required": ["timestamp_ns", "view", "names", "positions"],
}

CAPTURE_EVENT_SCHEMA = {
    "$schema": "https://json-schema.org/draft/2020-12/schema",
    "title": CAPTURE_EVENT_SCHEMA_NAME,
    "description": "A view was shot, or two views form a stereo pair.",
    "oneOf": [
        {
            "type": "object",
            "properties": {
                "event": {"const": "view"},
                "view": {"type": "integer", "minimum": 0},
                "timestamp_ns": {"type": "integer", "description": "exposure time, ns"},
                "settle_s": {"type": "number", "description": "wait after motion stopped"},
                "controller_T_base_tool0": {
                    "type": "array", "items": {"type": "number"}, "minItems": 16,
                    "maxItems": 16,
                    "description": "the controller's own flange pose at the view's joints "
                                   "(4x4 row-major, base frame, m), beside our FK on /tf"},
                "camera_settings": {
                    "type": "object",
                    "description": "exposure, gain, white balance, gamma the camera reported for "
                                   "this frame (names and units: armstereo.camera_settings)",
                    "additionalProperties": {"oneOf": [
                        {"type": "number"}, {"type": "array", "items": {"type": "number"}}]}},
                "device_timestamp_ns": {"type": "integer", "minimum": 0,
                                        "description": "the camera's own time stamp of the "
                                                       "frame (its clock), ns"},
                "device_frame": {"type": "integer", "minimum": 0,
                                 "description": "the camera's frame counter"},
            },
            "required": ["event", "view", "timestamp_ns", "settle_s"],
        },
        {
            "type": "object",
            "properties": {
                "event": {"const": "pair"},
                "pair": {"type": "integer", "minimum": 0},
                "left_view": {"type": "integer", "minimum": 0},
                "right_view": {"type": "integer", "minimum": 0},
                "commanded_baseline_m": {"type": "number"},
                "achieved_baseline_m": {"type": "number"},
                "direction": {"type": "string"},
                "viewpoint": {"type": "integer", "minimum": 0,
                              "description": "scan viewpoint the pair was shot from "
                                             "(armstereo scan only)"},
            },
            "required": ["event", "pair", "left_view", "right_view", "commanded_baseline_m",
                         "achieved_baseline_m", "direction"],
        },
    ],
}

# What each topic must carry: (schema name, message encoding). Protobuf schema names are the
# foxglove message types' full names; the writer registers their FileDescriptorSets.
PROTOBUF_TYPES = {
    TOPIC_IMAGE: CompressedImage,
    TOPIC_CALIBRATION: CameraCalibration,
    TOPIC_TF: FrameTransforms,
    TOPIC_DEPTH: RawImage,
    TOPIC_POINTS: PointCloud,
}
JSON_SCHEMAS = {
    TOPIC_JOINT_STATES: (JOINT_STATES_SCHEMA_NAME, JOINT_STATES_SCHEMA),
    TOPIC_EVENTS: (CAPTURE_EVENT_SCHEMA_NAME, CAPTURE_EVENT_SCHEMA),
}
EXPECTED_SCHEMAS: dict[str, tuple[str, str]] = {
    **{t: (cls.DESCRIPTOR.full_name, PROTOBUF) for t, cls in PROTOBUF_TYPES.items()},
    **{t: (name, JSON) for t, (name, _) in JSON_SCHEMAS.items()},
}


def json_schema_bytes(schema: dict) -> bytes:
    """The JSON Schema text stored in the MCAP Schema record."""
    return json.dumps(schema, indent=None, separators=(",", ":")).encode()
