"""The baseline sweep (the TASER experiment): planar targets at known distances, one capture
per baseline, measured against the true distance.

On the mock, targets are fronto-parallel textured squares at the given z-depths from the start
camera (``drivers.mock.scene.planar_target_scene``) and each target's pixels are known exactly.
On a real arm the user places the targets, measures their distances and names each one's pixel
box in the first (left) view. A target's measured distance is the median reconstructed depth
over its pixels in the original left view; ``density`` is the share of those pixels with a depth.
"""

from __future__ import annotations

import csv
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from armstereo.errors import ConfigError

BOX_SHRINK = 0.15  # ignore this share of each target box at every side (edges, occlusions)
MIN_DENSITY = 0.5  # a baseline "works" for a target when at least this share got a depth


@dataclass(frozen=True)
class Target:
    """A target to measure: its true distance (m) and its pixel box in the left view."""

    distance: float
    box: tuple[float, float, float, float]  # u_min, v_min, u_max, v_max

    @classmethod
    def parse(cls, text: str) -> Target:
        """From ``u0,v0,u1,v1=DIST`` (pixels in the first view, metres)."""
        try:
            box_text, dist_text = text.split("=")
            box = tuple(float(v) for v in box_text.split(","))
            dist = float(dist_text)
        except ValueError:
            box, dist = (), float("nan")
        if len(box) != 4 or not (box[0] < box[2] and box[1] < box[3]) or not dist > 0:
            raise ConfigError(f"--target must be u0,v0,u1,v1=DISTANCE with u0<u1, v0<v1, "
                              f"DISTANCE > 0 m, not {text!r}")
        return cls(dist, box)  # type: ignore[arg-type]


@dataclass(frozen=True)
class Measurement:
    """One target seen with one baseline."""

    baseline_m: float
    true_distance_m: float
    measured_distance_m: float  # NaN when no pixel of the target got a depth
    density: float
    pixel_rel_error: float  # median over the target's pixels of |Z - Z_true| / Z_true

    @property
    def error_m(self) -> float:
        return self.measured_distance_m - self.true_distance_m

    @property
    def rel_error(self) -> float:
        return abs(self.error_m) / self.true_distance_m


def measure_targets(depth: np.ndarray, targets: Sequence[Target], baseline: float,
                    truth: np.ndarray | None = None) -> list[Measurement]:
    """Median depth inside each (shrunken) target box; with ``truth``, only pixels whose true
    depth is the target's own (so a target's background never counts)."""
    out = []
    h, w = depth.shape
    for t in targets:
        u0, v0, u1, v1 = t.box
        du, dv = (u1 - u0) * BOX_SHRINK, (v1 - v0) * BOX_SHRINK
        cu0, cv0 = max(0, math.ceil(u0 + du)), max(0, math.ceil(v0 + dv))
        cu1, cv1 = min(w, math.floor(u1 - du) + 1), min(h, math.floor(v1 - dv) + 1)
        region = depth[cv0:cv1, cu0:cu1]
        mask = np.ones(region.shape, bool)
        if truth is not None:
            mask = np.abs(truth[cv0:cv1, cu0:cu1] - t.distance) <= 1e-3 * t.distance
        if not mask.any():
            raise ConfigError(f"target at {t.distance} m has no pixel inside the image")
        vals = region[mask]
        got = np.isfinite(vals) & (vals > 0)
        measured = float(np.median(vals[got])) if got.any() else float("nan")
        spread = (float(np.median(np.abs(vals[got] - t.distance))) / t.distance if got.any()
                  else float("nan"))
        out.append(Measurement(baseline, t.distance, measured, float(got.mean()), spread))
    return out


def best_baseline(results: Sequence[Measurement]) -> float | None:
    """The baseline with the lowest mean per-pixel relative error among those that measured
    every target with at least MIN_DENSITY coverage; None if none did."""
    scores = {}
    for b in sorted({m.baseline_m for m in results}):
        ms = [m for m in results if m.baseline_m == b]
        if all(m.density >= MIN_DENSITY and math.isfinite(m.measured_distance_m) for m in ms):
            scores[b] = float(np.mean([m.pixel_rel_error for m in ms]))
    return min(scores, key=scores.get) if scores else None


def write_csv(path: Path, results: Sequence[Measurement]) -> Path:
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["baseline_m", "true_distance_m", "measured_distance_m", "error_m",
                    "rel_error", "pixel_rel_error", "density"])
        for m in results:
            w.writerow([f"{m.baseline_m:.4f}", f"{m.true_distance_m:.4f}",
                        f"{m.measured_distance_m:.5f}", f"{m.error_m:.5f}",
                        f"{m.rel_error:.6f}", f"{m.pixel_rel_error:.6f}", f"{m.density:.4f}"])
    return path


def plot(path: Path, results: Sequence[Measurement], title: str) -> Path:
    """Measured vs true distance, one line per baseline, plus the relative error below."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax, ax_err) = plt.subplots(2, 1, figsize=(7, 8), sharex=True,
                                     gridspec_kw={"height_ratios": [3, 2]})
    true = sorted({m.true_distance_m for m in results})
    ax.plot(true, true, color="black", linestyle=":", label="true distance")
    for b in sorted({m.baseline_m for m in results}):
        ms = sorted((m for m in results if m.baseline_m == b), key=lambda m: m.true_distance_m)
        x = [m.true_distance_m for m in ms]
        ax.plot(x, [m.measured_distance_m for m in ms], marker="o", label=f"b = {b * 100:g} cm")
        ax_err.plot(x, [m.pixel_rel_error * 100 for m in ms], marker="o",
                    label=f"b = {b * 100:g} cm")
    ax.set_ylabel("measured distance (m)")
    ax.set_title(title)
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    ax_err.set_xlabel("true distance (m)")
    ax_err.set_ylabel("per-pixel |error| (median, %)")
    ax_err.set_yscale("log")
    ax_err.grid(alpha=0.3, which="both")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def format_table(results: Sequence[Measurement]) -> list[str]:
    """Rows: baselines; columns: true distances; cells: measured distance (median per-pixel
    relative error, %)."""
    dists = sorted({m.true_distance_m for m in results})
    head = "baseline | " + " | ".join(f"{d:.2f} m" for d in dists)
    lines = [head, "-" * len(head)]
    for b in sorted({m.baseline_m for m in results}):
        cells = []
        for d in dists:
            m = next(x for x in results if x.baseline_m == b and x.true_distance_m == d)
            cells.append("  no depth " if not math.isfinite(m.measured_distance_m) else
                         f"{m.measured_distance_m:.3f} ({m.pixel_rel_error * 100:.2f}%)")
        lines.append(f"{b * 100:6.1f} cm | " + " | ".join(cells))
    return lines


def run_sweep(baselines: Sequence[float], capture_one: Callable[[float], tuple],
              progress: Callable[[str], None] = lambda s: None) -> list[Measurement]:
    """For each baseline: ``capture_one(b) -> (depth_original, targets, truth_or_None)``,
    then measure every target."""
    results: list[Measurement] = []
    for i, b in enumerate(baselines, 1):
        progress(f"[{i}/{len(baselines)}] baseline {b * 100:g} cm")
        depth, targets, truth = capture_one(b)
        results += measure_targets(depth, targets, b, truth)
    return results


# -- the desk sweep (realistic mock profile) ---------------------------------------------------
# Planar targets facing the camera never break matching: they look the same from every
# baseline. On a desk the views of slanted and occluding surfaces differ more the longer the
# baseline, which is what limits the baseline on real scenes. On the realistic mock profile the
# sweep therefore captures the demo's desk scene once per baseline and scores every pixel both
# views see (the demo's measure), plus the reconstructed points' distance to the true surfaces.

SCENE_MIN_DENSITY = 0.9  # the product's density target: a baseline must keep it to count


@dataclass(frozen=True)
class SceneMeasurement:
    """The desk seen with one baseline: the demo's accuracy measures."""

    baseline_m: float
    median_rel_error: float  # median |Z - Z_true| / Z_true over the pixels both views see
    within_1pct: float
    density: float
    point_error_mm: float | None  # median distance of the points to the true surfaces


def best_scene_baseline(results: Sequence[SceneMeasurement]) -> float | None:
    """The baseline with the lowest median error among those keeping SCENE_MIN_DENSITY."""
    ok = [m for m in results if m.density >= SCENE_MIN_DENSITY
          and math.isfinite(m.median_rel_error)]
    return min(ok, key=lambda m: m.median_rel_error).baseline_m if ok else None


def format_scene_table(results: Sequence[SceneMeasurement]) -> list[str]:
    """One row per baseline: median error, share within 1 %, density, point error."""
    head = "baseline | median depth error | within 1 % | density | points (median)"
    lines = [head, "-" * len(head)]
    for m in sorted(results, key=lambda m: m.baseline_m):
        point = "-" if m.point_error_mm is None else f"{m.point_error_mm:.2f} mm"
        lines.append(f"{m.baseline_m * 100:6.1f} cm | {m.median_rel_error * 100:17.3f} % | "
                     f"{m.within_1pct * 100:8.1f} % | {m.density * 100:5.1f} % | {point}")
    return lines


def write_scene_csv(path: Path, results: Sequence[SceneMeasurement]) -> Path:
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["baseline_m", "median_rel_error", "within_1pct", "density",
                    "point_error_mm"])
        for m in results:
            w.writerow([f"{m.baseline_m:.4f}", f"{m.median_rel_error:.6f}",
                        f"{m.within_1pct:.4f}", f"{m.density:.4f}",
                        "" if m.point_error_mm is None else f"{m.point_error_mm:.4f}"])
    return path


def plot_scene(path: Path, results: Sequence[SceneMeasurement], title: str) -> Path:
    """Median depth error and density against the baseline."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    ms = sorted(results, key=lambda m: m.baseline_m)
    b = [m.baseline_m * 100 for m in ms]
    fig, (ax, ax_d) = plt.subplots(2, 1, figsize=(7, 7), sharex=True)
    ax.plot(b, [m.median_rel_error * 100 for m in ms], marker="o")
    ax.set_ylabel("median |depth error| (%)")
    ax.set_yscale("log")
    ax.set_title(title)
    ax.grid(alpha=0.3, which="both")
    ax_d.plot(b, [m.density * 100 for m in ms], marker="o", color="tab:green")
    ax_d.axhline(SCENE_MIN_DENSITY * 100, color="grey", linestyle=":")
    ax_d.set_ylabel("density (%)")
    ax_d.set_xlabel("baseline (cm)")
    ax_d.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
