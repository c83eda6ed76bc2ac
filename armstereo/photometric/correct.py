"""Photometric correction of a stereo pair before matching: what is done and what it did.

Two steps, each switchable (:class:`PhotometricOptions`):

1. **Vignetting**: both raw views are divided by the camera's fall-off
   (:class:`armstereo.photometric.vignetting.Vignetting`, from the mount file's optional
   ``[vignetting]`` section, which ``armstereo calibrate`` writes). The same spot of a plain
   surface is darker in the view where it sits nearer an image corner, by more than a
   low-texture surface's own contrast; a matcher comparing intensities reads that as depth.
2. **Exposure and white balance**: the rectified right view is scaled per channel to the left
   view's brightness (:func:`armstereo.photometric.exposure.pair_gains`). The left view stays
   as it was: it colours the point cloud.

:meth:`PhotometricOptions.record` and :func:`record` give what was done as JSON, for
``report.json`` and the reconstruction's metadata.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field

import numpy as np

from armstereo.errors import ConfigError
from armstereo.photometric.exposure import GAIN_TOLERANCE, apply_gains, pair_gains
from armstereo.photometric.vignetting import Vignetting, devignette

CHOICES = ("all", "vignetting", "exposure", "none")  # the command line's --photometric


@dataclass(frozen=True, kw_only=True)
class PhotometricOptions:
    """Which corrections run before matching. ``vignetting``: divide both views by the
    camera's fall-off ``model`` (when one is known: a mount file or recording without a
    ``[vignetting]`` section has none, and then nothing is divided). ``exposure``: equalise the
    pair's exposure and white balance from the images."""

    vignetting: bool = True
    exposure: bool = True
    model: Vignetting | None = field(default=None, compare=False)

    def __post_init__(self) -> None:
        for name in ("vignetting", "exposure"):
            if not isinstance(getattr(self, name), bool):
                raise ConfigError(f"photometric {name} must be True or False, got "
                                  f"{getattr(self, name)!r}")
        if self.model is not None and not isinstance(self.model, Vignetting):
            raise ConfigError(f"photometric model must be a Vignetting, got "
                              f"{type(self.model).__name__}")

    @classmethod
    def off(cls) -> PhotometricOptions:
        return cls(vignetting=False, exposure=False)

    @classmethod
    def from_choice(cls, choice: str) -> PhotometricOptions:
        """From the command line's ``--photometric all|vignetting|exposure|none``."""
        if choice not in CHOICES:
            raise ConfigError(f"--photometric must be one of {', '.join(CHOICES)}, got "
                              f"{choice!r}")
        return cls(vignetting=choice in ("all", "vignetting"),
                   exposure=choice in ("all", "exposure"))

    def with_model(self, model: Vignetting | None) -> PhotometricOptions:
        """These options with ``model`` as the fall-off unless one is already set."""
        if self.model is not None or model is None:
            return self
        return PhotometricOptions(vignetting=self.vignetting, exposure=self.exposure,
                                  model=model)

    @property
    def removes_vignetting(self) -> bool:
        return self.vignetting and self.model is not None


def as_options(photometric: bool | PhotometricOptions | None) -> PhotometricOptions:
    """``photometric=`` as the entry points take it: True (default: every correction whose
    data is known), False/None (none) or options."""
    if isinstance(photometric, PhotometricOptions):
        return photometric
    if photometric is True:
        return PhotometricOptions()
    if photometric is False or photometric is None:
        return PhotometricOptions.off()
    raise ConfigError(f"photometric must be True, False or a PhotometricOptions, got "
                      f"{photometric!r}")


def remove_vignetting(image1: np.ndarray, image2: np.ndarray,
                      options: PhotometricOptions) -> tuple[np.ndarray, np.ndarray]:
    """Both raw views with the fall-off divided out (unchanged when off or unknown)."""
    if not options.removes_vignetting:
        return image1, image2
    return devignette(image1, options.model), devignette(image2, options.model)


def equalize_exposure(left: np.ndarray, right: np.ndarray, max_disparity: int,
                      options: PhotometricOptions, *, left_mask=None, right_mask=None
                      ) -> tuple[np.ndarray, np.ndarray | None]:
    """(right view scaled to the left's brightness, the gains or None when off or not
    measurable) for a rectified pair."""
    if not options.exposure:
        return right, None
    gains = pair_gains(left, right, max_disparity, left_mask=left_mask, right_mask=right_mask)
    if gains is None:
        return right, None
    return apply_gains(right, gains), gains


def recorded_vignetting(metadata: dict[str, str]) -> Vignetting | None:
    """The camera's fall-off from a recording's metadata (the ``[vignetting]`` section of
    the recorded ``mount_toml``, for the image size of its ``[camera]``), or None: a mount file
    without the section (older files, a camera never photometrically calibrated), a recording
    without a mount, or a section that cannot be read (the images are then matched as they
    are)."""
    import tomllib

    from armstereo.errors import ArmstereoError

    text = metadata.get("mount_toml", "")
    if "[vignetting]" not in text:
        return None
    try:
        doc = tomllib.loads(text)
        width, height = int(doc["camera"]["width"]), int(doc["camera"]["height"])
        return Vignetting.from_dict(doc["vignetting"], width, height)
    except (tomllib.TOMLDecodeError, ArmstereoError, KeyError, TypeError, ValueError):
        return None


def for_recording(photometric: bool | PhotometricOptions | None,
                  metadata: dict[str, str]) -> PhotometricOptions:
    """``photometric`` (as :func:`as_options` takes it) with the recording's fall-off as the
    model when none is set."""
    return as_options(photometric).with_model(recorded_vignetting(metadata))


def record(options: PhotometricOptions, gains: np.ndarray | None) -> dict:
    """What the correction did, JSON-ready::

        {"vignetting": {"applied": bool, "model": {...} | None},
         "exposure": {"applied": bool, "gains": [..] | None}}

    ``exposure.applied`` is False when it was off, could not be measured, or every gain was
    within half a grey level of 1 (the image was left as it was)."""
    applied = gains is not None and bool(np.any(np.abs(np.asarray(gains) - 1.0) > GAIN_TOLERANCE))
    return {
        "vignetting": {"applied": options.removes_vignetting,
                       "requested": options.vignetting,
                       "model": options.model.as_dict() if options.model is not None else None},
        "exposure": {"applied": applied, "requested": options.exposure,
                     "gains": None if gains is None else [round(float(g), 5) for g in gains]},
    }


def record_json(entry: dict) -> str:
    """A record as one metadata string (MCAP metadata maps str to str)."""
    return json.dumps(entry, separators=(",", ":"))
