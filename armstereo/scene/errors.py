"""The scene-analysis error: the cloud was read, but it holds no usable support plane."""

from __future__ import annotations

from armstereo.errors import StereoError


class SceneError(StereoError):
    """Scene analysis cannot run on this cloud: no support plane, or a plane that is not
    roughly perpendicular to the expected up direction. Exit code 6, like the other
    "this input cannot be processed" errors of the reconstruction chain."""
