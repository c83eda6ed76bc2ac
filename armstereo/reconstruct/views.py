"""Two images with known camera poses -> a metric, coloured point cloud in the base frame.

This is armstereo's public entry point for users with their own images and poses (a ROS node,
another robot, a dataset); ``armstereo reconstruct`` calls it for each recorded pair::

    from armstereo import reconstruct_views
    result = reconstruct_views(img1, img2, K1, K2, T_base_cam1, T_base_cam2)
    result.points   # (N, 3) float32, base frame, metres
    result.colors   # (N, 3) uint8, RGB

Stages (each timed in ``timings_s``): ``rectify`` (Fusiello from the poses, lens distortion
removed in the same remap; the view from which the other lies to the right becomes "left"),
``match`` (Birchfield-Tomasi or SGBM on the rectified pair, as the ``stereo`` options say:
:class:`~armstereo.reconstruct.stereo_options.BirchfieldOptions` or ``SgbmOptions``) and
``triangulate``.
"""

from __future__ import annotations

import logging
import time
from contextlib import contextmanager
from dataclasses import dataclass, field, replace
from functools import cached_property

import numpy as np

from armstereo.camera_model import Intrinsics
from armstereo.errors import ConfigError, StereoError
from armstereo.io.images import colorize_disparity
from armstereo.photometric.correct import (
    PhotometricOptions,
    as_options,
    equalize_exposure,
    record,
    remove_vignetting,
)
from armstereo.reconstruct.rectified import RectifiedPair
from armstereo.reconstruct.rectify import RectificationPlan
from armstereo.reconstruct.stereo import disparity as match_pair
from armstereo.reconstruct.stereo_options import METHODS, StereoOptions, resolve_matcher
from armstereo.reconstruct.triangulate import (
    depth_from_disparity,
    depth_in_original_view,
    point_cloud,
)
from armstereo.reconstruct.window import DisparityWindow, choose_window, fit_to_canvas

log = logging.getLogger(__name__)

# min_disparity = 0 means "out to infinity"; the window's far end is put at this disparity.
INFINITY_DISPARITY_PX = 0.5


@dataclass(kw_only=True)
class Reconstruction:
    """Everything one pair produced. Images and depth maps are of the rectified left view unless
    named ``original``; points are in ``base`` (metres).

    ``swapped`` is True when the second input view became the rectified left image.
    ``colors_bgr`` is the points' colour as OpenCV images hold it, ``colors`` the same as RGB.
    ``stereo`` is the matcher's options object (its ``method`` is ``method``).
    """

    swapped: bool
    method: str
    stereo: StereoOptions | None = None
    window: DisparityWindow
    rectified: RectifiedPair
    disparity: np.ndarray
    points_base: np.ndarray
    colors_bgr: np.ndarray
    timings_s: dict[str, float] = field(default_factory=dict)
    # What the photometric correction did (armstereo.photometric.correct.record).
    photometric: dict = field(default_factory=dict)

    @property
    def points(self) -> np.ndarray:
        """(N, 3) float32 points in the base frame, metres."""
        return self.points_base

    @cached_property
    def colors(self) -> np.ndarray:
        """(N, 3) uint8 RGB colour of each point."""
        return np.ascontiguousarray(self.colors_bgr[:, ::-1])

    @cached_property
    def depth_rect(self) -> np.ndarray:
        """Depth (m) of each rectified left pixel along the rectified optical axis."""
        return depth_from_disparity(self.disparity, self.rectified.geometry)

    @cached_property
    def depth_original(self) -> np.ndarray:
        """Depth (m) for each pixel of the original left image (for scoring against truth)."""
        return depth_in_original_view(self.disparity, self.rectified)

    @cached_property
    def disparity_colorized(self) -> np.ndarray:
        """The disparity as a colour image over the searched window (PNG and MCAP share it)."""
        return colorize_disparity(self.disparity, 0, self.window.max_disparity)


def reconstruct_views(image1: np.ndarray, image2: np.ndarray, K1: np.ndarray, K2: np.ndarray,
                      T_base_cam1: np.ndarray, T_base_cam2: np.ndarray, *,
                      dist1: np.ndarray | None = None, dist2: np.ndarray | None = None,
                      method: str | None = None, near: float | None = None,
                      far: float | None = None, min_disparity: float | None = None,
                      max_disparity: float | None = None, disparity_budget: int | str = "auto",
                      stereo_options: dict | None = None,
                      stereo: StereoOptions | None = None,
                      photometric: bool | PhotometricOptions = True) -> Reconstruction:
    """Rectify, match and triangulate two views of a static scene.

    ``image1``/``image2``: uint8 grey or BGR images. ``K1``/``K2``: 3x3 camera matrices,
    ``dist1``/``dist2``: OpenCV distortion coefficients (None = none). ``T_base_cam1``/
    ``T_base_cam2``: 4x4 camera_optical poses in the base frame (metres); rotations a few 1e-6
    off orthonormal (printed to six decimals) are re-orthonormalized. The depth range to match is
    ``near``..``far`` (m), or equivalently ``max_disparity``..``min_disparity`` (pixels of the
    rectified pair, f b / Z; 0 = infinity); unset ends are guessed from the scene (the plane
    z = 0 of base) or defaults. ``disparity_budget`` caps the labels searched ("auto" = as the
    range needs, up to 256). ``stereo``: how to match, an options object
    (:class:`~armstereo.reconstruct.stereo_options.BirchfieldOptions`, the default, or
    ``SgbmOptions``); or ``method`` ("birchfield" or "sgbm") with the older ``stereo_options``
    dict of the matcher's keywords. The result records the options (``stereo``).
    ``photometric``: what is corrected before matching (:mod:`armstereo.photometric.correct`):
    True (default) equalises the pair's exposure and white balance and, when the options carry
    the camera's vignetting model (a mount file's ``[vignetting]``), divides it out; False
    corrects nothing. What was done is in ``result.photometric``.

    Raises ConfigError for bad options, StereoError when the pair cannot be rectified or
    matched (no baseline, views that do not overlap, mismatched images).
    """
    matcher = _matcher(method, stereo, stereo_options)
    timings: dict[str, float] = {}
    photo = as_options(photometric)
    with _timed(timings, "photometric"):
        image1, image2 = remove_vignetting(image1, image2, photo)
    with _timed(timings, "rectify"):
        # the poses are checked and the rectification solved once, for both steps below
        plan = RectificationPlan.from_views(_intrinsics(image1, K1, dist1, "1"), T_base_cam1,
                                            _intrinsics(image2, K2, dist2, "2"), T_base_cam2,
                                            snap=True)
        geometry0, swapped = plan.geometry(), plan.swapped
        near, far = _depth_range(geometry0, near, far, min_disparity, max_disparity)
        window = choose_window(geometry0, plan.left_intrinsics, plan.T_base_left_camera,
                               near=near, far=far, max_disparity=disparity_budget)
        rect = plan.rectify(image1, image2, depth_range=(window.near, window.far))
        window = fit_to_canvas(window, rect.geometry, auto=disparity_budget == "auto")
    with _timed(timings, "photometric", add=True):
        right, gains = equalize_exposure(rect.left, rect.right, window.max_disparity, photo,
                                         left_mask=rect.left_mask, right_mask=rect.right_mask)
        rect = rect if right is rect.right else replace(rect, right=right)
    log.debug("left = view %d%s, rotation %.0f deg, baseline %.1f mm, depth %.3f-%.3f m -> "
              "disparities 0..%d (%s)", 2 if swapped else 1, " (swapped)" if swapped else "",
              rect.rotation_deg, rect.baseline * 1000, window.near, window.far,
              window.max_disparity, window.source)
    with _timed(timings, "match"):
        disparity = match_pair(rect.left, rect.right, window.max_disparity, matcher,
                               min_disparity=0, left_mask=rect.left_mask,
                               right_mask=rect.right_mask)
    with _timed(timings, "triangulate"):
        points, colors = point_cloud(disparity, rect.geometry, rect.left)
    return Reconstruction(swapped=swapped, method=matcher.method, stereo=matcher,
                          window=window, rectified=rect,
                          disparity=disparity, points_base=points, colors_bgr=colors,
                          timings_s=timings, photometric=record(photo, gains))


def _matcher(method: str | None, stereo: StereoOptions | None,
             stereo_options: dict | None) -> StereoOptions:
    """The matcher's options from ``stereo`` or ``method`` and ``stereo_options``; ConfigError
    for an unknown method, both kinds of options or options of another method."""
    if method is not None and method not in METHODS:
        raise ConfigError(f"--method must be one of {', '.join(METHODS)}, got {method!r}")
    return resolve_matcher(method, stereo, stereo_options, error=ConfigError)


def _intrinsics(image: np.ndarray, K, dist, which: str) -> Intrinsics:
    """The view's intrinsics, its size from its image (checked)."""
    if not isinstance(image, np.ndarray) or image.ndim not in (2, 3) or image.size == 0:
        raise StereoError(f"image{which} must be a non-empty (H, W) or (H, W, 3) uint8 array")
    dist = np.zeros(5) if dist is None else np.asarray(dist, dtype=float).reshape(-1)
    return Intrinsics(int(image.shape[1]), int(image.shape[0]), np.asarray(K, dtype=float),
                      dist)


def _depth_range(geometry, near, far, min_disparity, max_disparity):
    """(near, far) in metres from whichever of near/far or max/min disparity is given."""
    fb = geometry.fx * geometry.baseline
    if max_disparity is not None:
        if near is not None:
            raise ConfigError("give near or max_disparity, not both")
        if not max_disparity > 0:
            raise ConfigError(f"max_disparity must be > 0 px, got {max_disparity}")
        near = fb / max_disparity
    if min_disparity is not None:
        if far is not None:
            raise ConfigError("give far or min_disparity, not both")
        if not min_disparity >= 0:
            raise ConfigError(f"min_disparity must be >= 0 px, got {min_disparity}")
        far = fb / max(float(min_disparity), INFINITY_DISPARITY_PX)
    return near, far


@contextmanager
def _timed(timings: dict[str, float], stage: str, add: bool = False):
    t0 = time.perf_counter()
    try:
        yield
    finally:
        timings[stage] = (timings.get(stage, 0.0) if add else 0.0) + time.perf_counter() - t0
