"""One recorded pair -> a metric, coloured point cloud in the robot's base frame.

The recording supplies both views' images, intrinsics and poses; :func:`reconstruct_pair`
decodes them (stage ``decode``) and hands them to
:func:`armstereo.reconstruct.views.reconstruct_views` (``rectify``, ``match``,
``triangulate``). Writing the products is :mod:`armstereo.reconstruct.outputs`.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from armstereo.errors import RecordingError
from armstereo.photometric.correct import PhotometricOptions
from armstereo.reconstruct.stereo_options import StereoOptions
from armstereo.reconstruct.views import Reconstruction, reconstruct_views
from armstereo.recording import Pair


@dataclass(kw_only=True)
class PairReconstruction(Reconstruction):
    """A :class:`Reconstruction` of recorded pair ``pair_index``: which recorded views became
    left and right, the left view's ground-truth depth (mock recordings) and capture time."""

    pair_index: int
    left_view: int  # recording view index that became the rectified left image
    right_view: int
    depth_truth: np.ndarray | None  # ground truth of the ORIGINAL left view, if recorded
    timestamp_ns: int
    source_pair: Pair = field(repr=False)

    @property
    def pipeline_time_s(self) -> float:
        """decode + photometric + rectify + match + triangulate + write (PLY), what the 0.5 s
        target counts."""
        stages = ("decode", "photometric", "rectify", "match", "triangulate", "write")
        return float(sum(self.timings_s.get(k, 0.0) for k in stages))


def _view_inputs(pair: Pair, which: str):
    """(image, intrinsics, T_base_camera) of one view, or RecordingError naming what is missing."""
    view = getattr(pair, which)
    T = getattr(view, "T_base_camera", None)
    if T is None or np.shape(T) != (4, 4) or not np.all(np.isfinite(T)):
        raise RecordingError(f"pair {pair.index}: view {view.index} has no camera pose")
    intr = getattr(view, "intrinsics", None)
    if intr is None:
        raise RecordingError(f"pair {pair.index}: view {view.index} has no camera calibration")
    image = view.image
    if image is None or np.size(image) == 0:
        raise RecordingError(f"pair {pair.index}: view {view.index} has no image")
    if (image.shape[1], image.shape[0]) != intr.size:
        raise RecordingError(f"pair {pair.index}: view {view.index} image is "
                             f"{image.shape[1]}x{image.shape[0]} but its calibration is "
                             f"{intr.width}x{intr.height}")
    return image, intr, np.asarray(T, dtype=float)


def reconstruct_pair(pair: Pair, *, method: str | None = None,
                     max_disparity: int | str = "auto", near: float | None = None,
                     far: float | None = None, stereo_options: dict | None = None,
                     stereo: StereoOptions | None = None,
                     photometric: bool | PhotometricOptions = True) -> PairReconstruction:
    """Rectify, match and triangulate one recorded pair (``armstereo.recording.Pair``);
    ``max_disparity`` is the matcher's budget ("auto" or a number of labels); ``stereo`` (an
    options object) or ``method`` and ``stereo_options`` say how to match, as
    :func:`~armstereo.reconstruct.views.reconstruct_views` takes them. ``photometric`` as
    :func:`~armstereo.reconstruct.views.reconstruct_views` takes it; the camera's vignetting
    is the options' model (``armstereo.photometric.correct.for_recording(photometric,
    recording.metadata)`` takes it from the recording's mount file).

    Raises RecordingError for a pair without poses, calibration or images, ConfigError for bad
    options and StereoError when the geometry cannot be rectified.
    """
    t0 = time.perf_counter()
    img1, intr1, T1 = _view_inputs(pair, "left")
    img2, intr2, T2 = _view_inputs(pair, "right")
    decode_s = time.perf_counter() - t0
    recon = reconstruct_views(img1, img2, intr1.K, intr2.K, T1, T2, dist1=intr1.dist,
                              dist2=intr2.dist, method=method, near=near, far=far,
                              disparity_budget=max_disparity, stereo_options=stereo_options,
                              stereo=stereo, photometric=photometric)
    left, right = (pair.right, pair.left) if recon.swapped else (pair.left, pair.right)
    fields = {f: getattr(recon, f) for f in Reconstruction.__dataclass_fields__}
    fields["timings_s"] = {"decode": decode_s, **recon.timings_s}
    return PairReconstruction(**fields, pair_index=pair.index, left_view=left.index,
                              right_view=right.index, depth_truth=getattr(left, "depth", None),
                              timestamp_ns=int(left.timestamp_ns), source_pair=pair)
