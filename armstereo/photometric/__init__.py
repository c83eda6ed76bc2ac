"""Photometric calibration and correction: the camera's vignetting (estimated by
``armstereo calibrate``, kept in the mount file) and the exposure and white-balance difference
between the two views of a pair (estimated from the images), removed before matching.

- :mod:`.vignetting`: the radial fall-off model, its mount-file section, its removal;
- :mod:`.exposure`: a pair's per-channel gain from its two rectified views;
- :mod:`.correct`: :class:`PhotometricOptions` (``photometric=`` of the entry points) and the
  record of what was done.
"""

from armstereo.photometric.correct import PhotometricOptions, as_options
from armstereo.photometric.vignetting import Vignetting, devignette

__all__ = ["PhotometricOptions", "Vignetting", "as_options", "devignette"]
