"""armstereo: a robot arm with a wrist camera as a 3D scanner.

The arm moves its one camera by a commanded baseline; forward kinematics of the actual joints
gives each view's pose; the pair is rectified (Fusiello), matched (Birchfield-Tomasi) and
triangulated into a point cloud in the robot's ``base`` frame.

For your own images and poses: ``from armstereo import reconstruct_views`` (see
:func:`armstereo.reconstruct.views.reconstruct_views`); how it matches:
``reconstruct_views(..., stereo=BirchfieldOptions(...))`` or ``SgbmOptions`` (both importable
from here too, :mod:`armstereo.reconstruct.stereo_options`).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

__version__ = "0.1.0"
__all__ = ["BirchfieldOptions", "SgbmOptions", "__version__", "reconstruct_views"]

if TYPE_CHECKING:
    from armstereo.reconstruct.stereo_options import BirchfieldOptions, SgbmOptions
    from armstereo.reconstruct.views import reconstruct_views


def __getattr__(name: str):
    # Lazy, so `import armstereo` (and every CLI command) stays light.
    if name == "reconstruct_views":
        from armstereo.reconstruct.views import reconstruct_views

        return reconstruct_views
    if name in ("BirchfieldOptions", "SgbmOptions"):
        from armstereo.reconstruct import stereo_options

        return getattr(stereo_options, name)
    raise AttributeError(f"module 'armstereo' has no attribute {name!r}")
