"""A recorded pair as if its camera had another mount: reconstruct old recordings with a new
calibration.

A recording keeps, per view, the flange pose (forward kinematics of the recorded joints, base
frame) and the mount the capture believed (``T_flange_camera`` and the intrinsics). The images
do not depend on what was believed, so a mount file written later by ``armstereo calibrate``
applies to them as it would have at capture time: each view's camera pose becomes
``T_base_flange @ T_flange_camera`` of the new mount and its intrinsics the new mount's.
"""

from __future__ import annotations

from dataclasses import replace

from armstereo.errors import ConfigError
from armstereo.mount import CameraMount
from armstereo.recording.contents import Pair, View


def remounted_view(view: View, mount: CameraMount) -> View:
    """``view`` with ``mount``'s hand-eye transform and intrinsics (scaled to the recorded
    image size when the camera ran a binned mode; ConfigError for another aspect ratio)."""
    intr = mount.intrinsics
    size = view.image_size or (view.intrinsics.size if view.intrinsics is not None else None)
    if size is not None and tuple(size) != intr.size:
        intr = intr.scaled(int(size[0]), int(size[1]))
    return replace(view, T_flange_camera=mount.T_flange_camera.copy(), intrinsics=intr)


def remounted(pair: Pair, mount: CameraMount) -> Pair:
    """``pair`` with both views remounted (module doc)."""
    if not isinstance(mount, CameraMount):
        raise ConfigError(f"a mount must be a CameraMount, got {type(mount).__name__}")
    return replace(pair, left=remounted_view(pair.left, mount),
                   right=remounted_view(pair.right, mount))
