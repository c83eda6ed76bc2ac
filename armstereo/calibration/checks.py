"""Is the calibration input good enough? One-line errors that say what to change.

A calibration that cannot be trusted is refused with :class:`CalibrationInputError` (a
ConfigError: exit 2), never returned with a bad number in it. Milder problems become warnings
(strings) in the report.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from armstereo.calibration.board import Detection
from armstereo.errors import ConfigError

MIN_VIEWS = 6  # usable views (board found, large enough); hand-eye plus leave-one-out
MIN_FOUND_FRACTION = 0.5  # found in fewer than this share of the views: the setup is wrong
MIN_CORNER_SPACING_PX = 10.0  # neighbouring corners closer than this: board too small
MIN_MAX_ROTATION_DEG = 15.0  # the views must span at least this rotation
MIN_AXIS_SPREAD_DEG = 10.0  # rotation axes spanning less than this are parallel for us
WEAK_AXIS_SPREAD_DEG = 25.0  # ... and less than this is weak: warn
MIN_USABLE_PAIRS = 3


class CalibrationInputError(ConfigError):
    """The views cannot give a trustworthy calibration; the message says what to change."""


def usable_views(detections: Sequence[Detection | None]) -> tuple[list[int], list[str]]:
    """Indices of views whose board was found and is large enough, plus warnings.

    Raises CalibrationInputError when too few views remain, naming why views were lost.
    """
    n = len(detections)
    missing = [i for i, d in enumerate(detections) if d is None]
    small = [i for i, d in enumerate(detections)
             if d is not None and d.spacing_px < MIN_CORNER_SPACING_PX]
    good = [i for i, d in enumerate(detections) if d is not None and i not in small]
    warnings = []
    found = n - len(missing)
    if n < MIN_VIEWS:
        raise CalibrationInputError(f"only {n} views recorded (need >= {MIN_VIEWS}); record "
                                    "more views (15 is a good number)")
    if found < max(MIN_VIEWS, MIN_FOUND_FRACTION * n):
        raise CalibrationInputError(
            f"board not found in {len(missing)} of {n} views ({_views(missing)}); keep the "
            "whole board in the image: start with it centred 0.3-0.6 m from the camera, "
            "light it evenly, or plan smaller tilts")
    if len(good) < MIN_VIEWS:
        spacing = np.median([detections[i].spacing_px for i in small])
        raise CalibrationInputError(
            f"the board is too small in the image in {len(small)} of {found} views (corners "
            f"{spacing:.1f} px apart, need >= {MIN_CORNER_SPACING_PX:g} px); use a board with "
            "larger squares or start closer to it")
    if missing:
        warnings.append(f"board not found in {len(missing)} of {n} views ({_views(missing)})")
    if small:
        warnings.append(f"{len(small)} views dropped: board too small (corners closer than "
                        f"{MIN_CORNER_SPACING_PX:g} px) in views {_views(small)}")
    return good, warnings


def _views(idx: Sequence[int], limit: int = 8) -> str:
    shown = ", ".join(str(i) for i in idx[:limit])
    return "views " + shown + (", ..." if len(idx) > limit else "") if idx else "none"
