"""A camera image with its exposure time: what cameras deliver and recordings store."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass
class Frame:
    """One camera image (numpy uint8, BGR when colour). ``timestamp_ns`` is the exposure time
    on the clock the arm and camera share.

    ``depth`` is ground-truth z-depth in metres (float32, NaN where nothing was hit); only
    simulated cameras provide it.

    What the device says about this very frame, where it says it (None otherwise):
    ``settings`` the exposure, gain, white balance and gamma it was taken with (names and units
    in :mod:`armstereo.camera_settings`), ``device_timestamp_ns`` the device's own time stamp
    of it (the device's clock, not the shared one) and ``device_frame`` its frame counter.
    """

    image: np.ndarray
    timestamp_ns: int
    depth: np.ndarray | None = None
    settings: dict[str, float | tuple[float, ...]] | None = None
    device_timestamp_ns: int | None = None
    device_frame: int | None = None
