"""Greedy next-best view for ``armstereo scan --views auto:N``.

Candidates are the reachable viewpoints of a ``sphere:K`` layout around the target
(K = max(CANDIDATES_MIN, CANDIDATES_PER_VIEW * N), from ``--elevation`` up). After every pair
the scan reconstructs it and fuses its depth into a coarse TSDF over the region of interest
(a cube of ``ROI_HALF_RADII * radius`` either side of the target, base frame); the volume's
observed mask (weight > 0: seen as free space or as surface) says what is known. The next
viewpoint is the candidate whose camera sees the most unknown space: rays through every
``RAY_STRIDE_PX``-th pixel are marched through the volume from the camera, and a ray counts
when the first voxel it meets that is not known free space is unknown (not an observed
surface, not outside the box). Once something is observed, the box the rays are counted in
shrinks to the observed surface band grown by ``SURFACE_BOX_GROW_M``: otherwise the empty
air at the cube's corners, outside the first view's frustum, outweighs the shadows behind
objects that a new view would fill. Ties go to the candidate nearest in joints. The scan stops
when the budget N is spent, no candidate is left, or the best gain falls below
``MIN_GAIN_SHARE`` of the first view's.

Safety: the order is chosen while scanning, so the whole tour cannot be checked before the
arm moves. What can be is: before anything moves, every candidate's baseline move and its
joint moves from and back to the start pose pass capture's checks (a candidate that fails is
dropped with the reason), as do the speed caps and the start pose. While scanning, the
direct joint move from the current viewpoint to the chosen one is checked before it is made;
if it fails, the arm goes by way of the start pose (both halves checked before anything
moved). So every move the arm makes has passed the checks before it starts.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Iterator
from dataclasses import dataclass, field, replace

import numpy as np
from numba import njit

from armstereo.camera_model import Intrinsics
from armstereo.capture.plan import (
    CaptureSettings,
    Check,
    Checked,
    PairStep,
    Step,
    Workspace,
    check_speed,
    check_start,
    validate_settings,
)
from armstereo.capture.scan_plan import DroppedView, ScanPlan, ScanView
from armstereo.capture.tour import baseline_leg, check_legs, joint_leg
from armstereo.errors import ArmstereoError, ConfigError
from armstereo.frame import Frame
from armstereo.fusion.tsdf import DepthFrame, Roi, TsdfVolume
from armstereo.robot.arm_model import ArmModel

log = logging.getLogger(__name__)

CANDIDATES_MIN = 24
CANDIDATES_PER_VIEW = 3
MAX_AUTO_VIEWS = 50
VOXEL_M = 0.008  # coarse: the mask only has to say which space was seen
TRUNC_VOXELS = 3
RAY_STRIDE_PX = 8
MIN_GAIN_SHARE = 0.05
ROI_HALF_RADII = 0.5
STEP_VOXELS = 0.5  # ray marching step
BOX_PERCENTILE = 1.0  # per side, surface voxels left out of the box
SURFACE_BOX_GROW_M = 0.02  # the gain is counted around the surfaces seen so far, this much wider


def parse_auto(text: str) -> int | None:
    """N for ``auto:N`` (1..MAX_AUTO_VIEWS), None for any other layout; ConfigError for a
    malformed ``auto:`` value."""
    label = text.strip().lower()
    if not label.startswith("auto"):
        return None
    head, _, count = label.partition(":")
    if head != "auto" or not count.isdigit() or not 1 <= int(count) <= MAX_AUTO_VIEWS:
        raise ConfigError(f"--views auto:N needs N in 1..{MAX_AUTO_VIEWS}, not {text!r}")
    return int(count)


def candidate_layout(budget: int) -> str:
    """The ``sphere:K`` layout the candidates of ``auto:budget`` come from."""
    return f"sphere:{max(CANDIDATES_MIN, CANDIDATES_PER_VIEW * budget)}"


def target_roi(target: np.ndarray, radius: float) -> Roi:
    """The region of interest of an auto scan: a cube around ``target`` (base frame, m)."""
    half = ROI_HALF_RADII * radius
    t = np.asarray(target, float)
    return Roi(tuple(t - half), tuple(t + half))


def surface_box(volume: TsdfVolume, grow_m: float = SURFACE_BOX_GROW_M
                ) -> tuple[np.ndarray, np.ndarray]:
    """Voxel index bounds (lo, hi), inclusive, of the observed surface band (weight > 0,
    tsdf < 1; BOX_PERCENTILE to 100 - BOX_PERCENTILE per axis) grown by ``grow_m``; the whole
    volume while nothing is observed."""
    band = np.nonzero((volume.weight > 0) & (volume.tsdf < 1.0))
    shape = np.array(volume.shape)
    if len(band[0]) == 0:
        return np.zeros(3, np.int64), shape - 1
    grow = int(math.ceil(grow_m / volume.voxel))
    # Percentiles, not extremes: a few wrong matches far below the table must not stretch it.
    lo = np.floor(np.percentile(np.stack(band, axis=1), BOX_PERCENTILE, axis=0)) - grow
    hi = np.ceil(np.percentile(np.stack(band, axis=1), 100 - BOX_PERCENTILE, axis=0)) + grow
    return np.maximum(lo, 0).astype(np.int64), np.minimum(hi, shape - 1).astype(np.int64)


def visible_unknown(volume: TsdfVolume, T_base_camera: np.ndarray, K: np.ndarray,
                    size: tuple[int, int], stride: int = RAY_STRIDE_PX,
                    box: tuple[np.ndarray, np.ndarray] | None = None) -> int:
    """How many of the camera's rays (every ``stride``-th pixel of an image of ``size`` (w, h)
    with pinhole ``K`` at ``T_base_camera``, base frame) meet unknown space of ``volume``
    before an observed surface, inside the voxel index ``box`` (lo, hi inclusive; default
    :func:`surface_box`)."""
    lo, hi = surface_box(volume) if box is None else box
    w, h = size
    u, v = np.meshgrid(np.arange(stride / 2, w, stride), np.arange(stride / 2, h, stride))
    rays = np.stack([(u.ravel() - K[0, 2]) / K[0, 0], (v.ravel() - K[1, 2]) / K[1, 1],
                     np.ones(u.size)], axis=1)
    dirs = rays @ T_base_camera[:3, :3].T
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    return int(_count_unknown(volume.tsdf, volume.weight, volume.origin, volume.voxel,
                              np.ascontiguousarray(T_base_camera[:3, 3], dtype=np.float64),
                              np.ascontiguousarray(dirs), STEP_VOXELS * volume.voxel,
                              np.asarray(lo, np.int64), np.asarray(hi, np.int64)))


@njit(cache=True, nogil=True)
def _count_unknown(tsdf, weight, origin, voxel, eye, dirs, step, ilo, ihi):  # pragma: no cover
    nx, ny, nz = tsdf.shape
    count = 0
    for r in range(dirs.shape[0]):
        t0, t1 = 0.0, 1e9
        inside = True
        for a in range(3):  # slab test: where the ray is inside the box
            d = dirs[r, a]
            lo_a = origin[a] + (ilo[a] - 0.5) * voxel
            hi_a = origin[a] + (ihi[a] + 0.5) * voxel
            if abs(d) < 1e-12:
                if eye[a] < lo_a or eye[a] > hi_a:
                    inside = False
                continue
            ta, tb = (lo_a - eye[a]) / d, (hi_a - eye[a]) / d
            if ta > tb:
                ta, tb = tb, ta
            t0, t1 = max(t0, ta), min(t1, tb)
        if not inside or t0 >= t1:
            continue
        t = t0
        while t <= t1:
            i = int(round((eye[0] + t * dirs[r, 0] - origin[0]) / voxel))
            j = int(round((eye[1] + t * dirs[r, 1] - origin[1]) / voxel))
            k = int(round((eye[2] + t * dirs[r, 2] - origin[2]) / voxel))
            if ilo[0] <= i <= ihi[0] and ilo[1] <= j <= ihi[1] and ilo[2] <= k <= ihi[2] \
                    and 0 <= i < nx and 0 <= j < ny and 0 <= k < nz:
                if weight[i, j, k] <= 0.0:
                    count += 1
                    break
                if tsdf[i, j, k] < 0.0:  # at or behind an observed surface
                    break
            t += step
    return count


@dataclass
class AutoTour(Checked):
    """A scan whose viewpoints are chosen while scanning (module docstring); runs in
    :func:`armstereo.capture.run.run_capture` with :meth:`observer` as its ``on_view``.

    ``scan`` holds the candidates that passed their checks (``dropped`` those that did not);
    ``chosen`` logs every pick: viewpoint, rays that saw unknown space, candidates left.
    """

    model: ArmModel
    scan: ScanPlan
    settings: CaptureSettings
    budget: int
    roi: Roi
    checks: list[Check]
    duration_s: float
    box: Workspace
    method: str = "birchfield"
    chosen: list[dict] = field(default_factory=list)
    stop_reason: str = ""
    detours: int = 0

    def __post_init__(self) -> None:
        self.volume = TsdfVolume(self.roi, VOXEL_M, TRUNC_VOXELS * VOXEL_M, threads=1)
        self._baselines = {v.index: baseline_leg(self.model, v, self.settings)
                           for v in self.scan.views}
        self._left: tuple[Frame, np.ndarray] | None = None
        self._intrinsics: Intrinsics | None = None

    @property
    def q_start(self) -> np.ndarray:
        return np.asarray(self.scan.q_start, float)

    def describe(self) -> list[str]:
        lines = self.scan.describe()
        lines[0] = lines[0].replace("scan plan:", f"scan plan: auto:{self.budget} from", 1)
        lim = self.settings.limits
        lines += [f"  next-best view: up to {self.budget} of these candidates, chosen while "
                  f"scanning by the unknown space they see in {self.roi} (base frame, m)",
                  f"  speed caps: {lim.joint_speed:.2f} rad/s, {lim.joint_acceleration:.2f} "
                  f"rad/s^2 (joint moves); {lim.linear_speed:.3f} m/s, "
                  f"{lim.linear_acceleration:.2f} m/s^2 (baseline moves); settle "
                  f"{self.settings.settle_s:.2f} s per view; at most {self.duration_s:.1f} s",
                  "  pre-flight checks (every candidate's baseline move and its joint moves "
                  "from and back to the start):"]
        lines += [f"    [{'ok' if c.ok else 'FAIL'}] {c.name}: {c.detail}" for c in self.checks]
        return lines

    # ------------------------------------------------------------------------- while scanning
    def observer(self, intrinsics: Intrinsics, vignetting=None):
        """The ``on_view`` hook for run_capture: fuses each pair once its right view is in
        (``vignetting``: the camera's fall-off, removed before matching, if known)."""
        self._intrinsics = intrinsics
        self._vignetting = vignetting
        return self._observe

    def _observe(self, view: int, frame: Frame, T_base_camera: np.ndarray) -> None:
        if view % 2 == 0:
            self._left = (frame, T_base_camera)
            return
        if self._left is None:
            return
        left, self._left = self._left, None
        from armstereo.photometric.correct import PhotometricOptions
        from armstereo.reconstruct.views import reconstruct_views

        intr = self._intrinsics
        try:
            recon = reconstruct_views(left[0].image, frame.image, intr.K, intr.K, left[1],
                                      T_base_camera, dist1=intr.dist, dist2=intr.dist,
                                      method=self.method,
                                      photometric=PhotometricOptions(
                                          model=getattr(self, "_vignetting", None)))
        except ArmstereoError as err:  # the scan goes on; this pair just adds no knowledge
            log.warning("next-best view: pair of views %d, %d not fused: %s", view - 1, view,
                        err)
            return
        g = recon.rectified.geometry
        self.volume.integrate(DepthFrame(np.asarray(recon.depth_rect, np.float32), g.K_left,
                                         g.T_base_rectleft))

    def steps(self) -> Iterator[Step]:
        """Capture steps, decided one viewpoint at a time (module docstring)."""
        s = self.settings
        remaining = {v.index: v for v in self.scan.views}
        prev: ScanView | None = None
        first_gain = None
        for k in range(self.budget):
            pick = self._pick(remaining, prev, first_gain)
            if pick is None:
                break
            v, gain = pick
            first_gain = first_gain or max(gain, 1)
            del remaining[v.index]
            if prev is not None and not self._direct_ok(prev, v):
                self.detours += 1
                yield Step("joints", self.q_start, self._joint_s(self._q_end(prev),
                                                                 self.q_start),
                           say=f"by way of the start pose to viewpoint {v.index}")
                prev = None
            yield Step("joints", v.q_left, self._joint_s(self._q_end(prev), v.q_left),
                       view=2 * k, say=f"moving to viewpoint {v.index} (auto {k + 1}/"
                       f"{self.budget}: {gain} rays see unknown space)")
            yield Step("linear", self.model.flange_pose_for_camera(v.T_base_right),
                       self._baselines[v.index].duration_s, view=2 * k + 1,
                       pair=PairStep(k, 2 * k, 2 * k + 1, s.baseline, s.direction_label,
                                     v.index),
                       say=f"baseline move at viewpoint {v.index}")
            prev = v
        else:
            self.stop_reason = f"budget of {self.budget} viewpoints spent"
        yield Step("joints", self.q_start, self._joint_s(self._q_end(prev), self.q_start),
                   say="returning to the start")

    def _pick(self, remaining: dict[int, ScanView], prev: ScanView | None,
              first_gain: int | None) -> tuple[ScanView, int] | None:
        if not remaining:
            self.stop_reason = "no candidate left"
            return None
        intr = self._intrinsics
        q = self._q_end(prev)
        box = surface_box(self.volume)
        scored = [(visible_unknown(self.volume, v.T_base_camera, intr.K, intr.size, box=box),
                   -float(np.abs(v.q_left - q).max()), v) for v in remaining.values()]
        gain, _, best = max(scored, key=lambda x: (x[0], x[1]))
        if first_gain is not None and gain < MIN_GAIN_SHARE * first_gain:
            self.stop_reason = (f"best gain {gain} rays < {MIN_GAIN_SHARE:.0%} of the first "
                                f"view's {first_gain}")
            return None
        self.chosen.append({"viewpoint": best.index, "gain_rays": int(gain),
                            "candidates": len(remaining)})
        return best, int(gain)

    def _direct_ok(self, a: ScanView, b: ScanView) -> bool:
        leg = joint_leg(self._q_end(a), b.q_left, f"viewpoint {a.index} -> viewpoint "
                        f"{b.index}", self.settings)
        return all(c.ok for c in check_legs(self.model, [leg], self.settings, self.box))

    def _q_end(self, v: ScanView | None) -> np.ndarray:
        if v is None:
            return self.q_start
        leg = self._baselines[v.index]
        return v.q_right if leg.samples is None else leg.samples[-1]

    def _joint_s(self, q_from: np.ndarray, q_to: np.ndarray) -> float:
        return joint_leg(q_from, q_to, "", self.settings).duration_s


def plan_auto(model: ArmModel, candidates: ScanPlan, settings: CaptureSettings, budget: int,
              *, method: str = "birchfield") -> AutoTour:
    """Check every candidate of ``candidates`` (baseline move, joint moves from and back to
    the start) and the start pose and speed caps; an :class:`AutoTour` of up to ``budget``
    viewpoints. Never raises for a failed check; call ``require_ok()`` before moving."""
    settings = replace(settings, baseline=candidates.baseline,
                       direction=np.array([1.0, 0.0, 0.0]), direction_label="x",
                       pairs=budget)
    validate_settings(replace(settings, pairs=1))
    box = settings.workspace or Workspace.around(model)
    q0 = np.asarray(candidates.q_start, float)
    kept, dropped, legs = [], list(candidates.dropped), []
    for v in candidates.views:
        base = baseline_leg(model, v, settings)
        q_end = v.q_right if base.samples is None else base.samples[-1]
        own = [joint_leg(q0, v.q_left, f"start -> viewpoint {v.index}", settings), base,
               joint_leg(q_end, q0, f"viewpoint {v.index} -> start", settings)]
        bad = [c for c in check_legs(model, own, settings, box) if not c.ok]
        if bad:
            dropped.append(DroppedView(v.index, v.azimuth_deg, v.elevation_deg, bad[0].name,
                                       bad[0].detail))
            continue
        kept.append(v)
        legs += own
    scan = replace(candidates, views=kept, dropped=sorted(dropped, key=lambda d: d.index))
    checks = [check_speed(settings.limits), check_start(model, q0, settings),
              Check("viewpoints", bool(kept), f"{len(kept)} of "
                    f"{len(kept) + len(dropped)} candidates pass their checks")]
    if legs:
        checks += check_legs(model, legs, settings, box)
    # At most: the budget's slowest candidates, each reached from and left for the start.
    per_view = sorted((legs[i].duration_s + legs[i + 1].duration_s + legs[i + 2].duration_s
                       for i in range(0, len(legs), 3)), reverse=True)
    duration = sum(per_view[:budget]) + 2 * min(budget, len(kept)) * settings.settle_s
    return AutoTour(model, scan, settings, budget, target_roi(candidates.target,
                                                              candidates.radius),
                    checks, duration, box, method=method)
