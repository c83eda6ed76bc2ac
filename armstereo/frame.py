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
    """

    image: np.ndarray
    timestamp_ns: int
    depth: np.ndarray | None = None
