"""Camera intrinsics and hand-eye calibration of a wrist camera on a UR arm.

Pure computation, data in and data out (nothing here moves an arm or opens a device):

- :mod:`board`: ``--board`` specs, corner coordinates, detection, rendering.
- :mod:`views`: diverse, checked arm poses around a board (``plan_calibration_views``).
- :mod:`calibrate`: ``calibrate_from_views`` / ``calibrate_from_detections`` -> mount + report.
- :mod:`intrinsics`, :mod:`handeye`, :mod:`refine`, :mod:`report`: the steps.
- :mod:`mount_file`: the mount TOML and ``truth_error`` (simulations).
- :mod:`session`: calibration recordings (metadata, reading back for ``--from``).
- :mod:`synthetic`: simulated sessions with a known truth.

See docs/calibration.md.
"""

from armstereo.calibration.board import Board, Detection, detect_board, parse_board
from armstereo.calibration.calibrate import (
    Calibration,
    CalibrationOptions,
    calibrate_from_detections,
    calibrate_from_views,
)
from armstereo.calibration.checks import CalibrationInputError
from armstereo.calibration.mount_file import mount_toml, truth_error
from armstereo.calibration.views import (
    CalibrationViewPlan,
    ViewPlanSettings,
    board_in_start_view,
    plan_calibration_views,
)

__all__ = [
    "Board", "Calibration", "CalibrationInputError", "CalibrationOptions",
    "CalibrationViewPlan", "Detection", "ViewPlanSettings", "board_in_start_view",
    "calibrate_from_detections",
    "calibrate_from_views", "detect_board", "mount_toml", "parse_board",
    "plan_calibration_views", "truth_error",
]
