"""The camera-motion study: how each F estimator's error depends on the camera's motion.

After the naval thesis' experiment: synthetic ``cube`` and ``cloud`` scenes
(:mod:`~armstereo.epipolar.study_scenes`), seen before and after a ``rotation_only``,
``lateral``, ``forward`` or ``general`` motion, with perfect points and with Gaussian pixel
noise, estimated by every method of :data:`~armstereo.epipolar.fundamental.METHODS`.
Optionally a share of the matches is replaced by gross outliers (uniform over image 2); they
are left out of every error below. Per configuration and method, pooled over the inlier points
of all trials:

* ``epipolar``: Sampson distance of the observed (noisy) points under the estimated F;
* ``reprojection``: reprojection error after optimal triangulation, same points;
* ``truth``: Sampson distance of the noise-free points under the estimated F, i.e. how far the
  estimate is from the real geometry (undefined for ``rotation_only``: there is none);
* ``failed``: trials where the estimator raised; ``flagged``: share of trials whose matches
  :func:`~armstereo.epipolar.fundamental.check_not_degenerate` refuses.

The estimators run with ``allow_degenerate=True`` so the table shows what they return where
armstereo would refuse. Everything is seeded: the same options give the same numbers.
"""

from __future__ import annotations

import csv
import logging
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from armstereo.epipolar.errors import EpipolarError
from armstereo.epipolar.fundamental import (
    DEFAULT_THRESHOLD_PX,
    METHODS,
    check_not_degenerate,
    estimate_fundamental,
)
from armstereo.epipolar.metrics import reprojection_error, sampson_distance
from armstereo.epipolar.study_scenes import IMAGE_SIZE, MOTIONS, SCENES, two_views

log = logging.getLogger(__name__)

DEFAULT_NOISE_PX = 0.5
DEFAULT_TRIALS = 10
DEFAULT_POINTS = 100
CSV_FIELDS = ("scene", "motion", "noise_px", "method", "trials", "failed", "flagged",
              "epipolar_mean_px", "epipolar_median_px", "reprojection_mean_px",
              "reprojection_median_px", "truth_mean_px", "truth_median_px", "time_ms")


@dataclass(frozen=True)
class StudyConfig:
    """What to run. ``noise_px`` is the noisy level (a perfect run is always added);
    ``outliers`` the share of matches replaced by gross outliers in every run."""

    noise_px: float = DEFAULT_NOISE_PX
    outliers: float = 0.0
    trials: int = DEFAULT_TRIALS
    points: int = DEFAULT_POINTS
    seed: int = 0
    scenes: tuple[str, ...] = SCENES
    motions: tuple[str, ...] = MOTIONS
    methods: tuple[str, ...] = METHODS


@dataclass
class StudyRow:
    """One (scene, motion, noise, method) cell; errors in px, NaN when nothing was measured."""

    scene: str
    motion: str
    noise_px: float
    method: str
    trials: int = 0
    failed: int = 0
    flagged: float = 0.0
    epipolar_mean_px: float = float("nan")
    epipolar_median_px: float = float("nan")
    reprojection_mean_px: float = float("nan")
    reprojection_median_px: float = float("nan")
    truth_mean_px: float = float("nan")
    truth_median_px: float = float("nan")
    time_ms: float = float("nan")
    _errors: dict[str, list[np.ndarray]] = field(default_factory=dict, repr=False)


def run_study(config: StudyConfig = StudyConfig(),
              progress: Callable[[str], None] = lambda s: None) -> list[StudyRow]:
    """Run every configuration; returns one row per (scene, motion, noise level, method)."""
    rows = []
    for scene in config.scenes:
        for motion in config.motions:
            for noise in (0.0, config.noise_px):
                progress(f"{scene}, {motion} motion, noise {noise:g} px")
                rows += _configuration(scene, motion, noise, config)
    return rows


def _configuration(scene: str, motion: str, noise: float, config: StudyConfig) -> list[StudyRow]:
    # one generator per configuration: adding a method or a scene leaves the others' data alone
    seed = [config.seed, SCENES.index(scene), MOTIONS.index(motion), int(round(noise * 1000))]
    rng = np.random.default_rng(seed)
    rows = {m: StudyRow(scene, motion, noise, m, trials=config.trials) for m in config.methods}
    flagged, times = 0, {m: [] for m in config.methods}
    for trial in range(config.trials):
        views = two_views(scene, motion, config.points, rng)
        x1 = views.x1 + rng.normal(0.0, noise, views.x1.shape)
        x2 = views.x2 + rng.normal(0.0, noise, views.x2.shape)
        bad = rng.random(len(x2)) < config.outliers
        x2[bad] = rng.uniform((0, 0), IMAGE_SIZE, (int(bad.sum()), 2))
        flagged += _is_flagged(x1[~bad], x2[~bad])
        for method in config.methods:
            t0 = time.perf_counter()
            try:
                F, _ = estimate_fundamental(x1, x2, method, seed=trial, allow_degenerate=True)
            except EpipolarError:
                rows[method].failed += 1
                continue
            times[method].append(time.perf_counter() - t0)
            _collect(rows[method], F, x1[~bad], x2[~bad], views.x1[~bad], views.x2[~bad],
                     motion)
    for method, row in rows.items():
        row.flagged = flagged / config.trials
        _summarise(row, times[method])
    return list(rows.values())


def _is_flagged(x1: np.ndarray, x2: np.ndarray) -> bool:
    try:
        check_not_degenerate(x1, x2, DEFAULT_THRESHOLD_PX)
    except EpipolarError:
        return True
    return False


def _collect(row: StudyRow, F, x1, x2, true1, true2, motion: str) -> None:
    errs = row._errors
    errs.setdefault("epipolar", []).append(sampson_distance(F, x1, x2))
    errs.setdefault("reprojection", []).append(reprojection_error(F, x1, x2))
    if motion != "rotation_only":
        errs.setdefault("truth", []).append(sampson_distance(F, true1, true2))


def _summarise(row: StudyRow, times: list[float]) -> None:
    for name, parts in row._errors.items():
        e = np.concatenate(parts)
        setattr(row, f"{name}_mean_px", float(np.mean(e)))
        setattr(row, f"{name}_median_px", float(np.median(e)))
    if times:
        row.time_ms = 1000.0 * float(np.median(times))


# --------------------------------------------------------------------------------- writing
def write_csv(rows: list[StudyRow], path: Path) -> Path:
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=CSV_FIELDS)
        w.writeheader()
        for r in rows:
            d = {k: v for k, v in asdict(r).items() if k in CSV_FIELDS}
            w.writerow({k: (f"{v:.6g}" if isinstance(v, float) else v) for k, v in d.items()})
    return path


def _cell(v: float) -> str:
    return "n/a" if not np.isfinite(v) else f"{v:.3f}" if v < 100 else f"{v:.3g}"


def markdown_table(rows: list[StudyRow], noise: float, measure: str) -> list[str]:
    """A Markdown table (scene/motion rows x method columns) of one measure at one noise."""
    methods = list(dict.fromkeys(r.method for r in rows))
    sel = [r for r in rows if r.noise_px == noise]
    keys = list(dict.fromkeys((r.scene, r.motion) for r in sel))
    out = ["| scene | motion | " + " | ".join(methods) + " |",
           "|---|---|" + "---|" * len(methods)]
    for scene, motion in keys:
        cells = []
        for m in methods:
            r = _find(sel, scene, motion, noise, m)
            cells.append(_cell(getattr(r, measure)) + (f" ({r.failed} failed)" if r.failed
                                                       else ""))
        out.append(f"| {scene} | {motion} | " + " | ".join(cells) + " |")
    return out


def write_markdown(rows: list[StudyRow], config: StudyConfig, path: Path) -> Path:
    lines = ["# Camera-motion study of fundamental-matrix estimators",
             "", f"`armstereo study epipolar --noise {config.noise_px:g} --trials "
             f"{config.trials} --outliers {config.outliers:g}` (seed {config.seed}, "
             f"{config.points} points per view of which {config.outliers:.0%} gross outliers, "
             f"{config.trials} trials per cell). Errors in pixels, pooled over the inlier points "
             "of all trials. `truth` = Sampson distance of the noise-free points under the "
             "estimate (n/a for rotation only: there is no true epipolar geometry).", ""]
    for noise in (config.noise_px, 0.0):
        for measure, title in (("truth_mean_px", "mean truth error"),
                               ("epipolar_median_px", "median epipolar (Sampson) error"),
                               ("reprojection_median_px", "median reprojection error")):
            lines += [f"## {title}, noise {noise:g} px", ""]
            lines += markdown_table(rows, noise, measure) + [""]
    flagged = {(r.scene, r.motion): r.flagged for r in rows if r.noise_px == config.noise_px}
    lines += [f"## Refused as degenerate (share of trials, noise {config.noise_px:g} px)", ""]
    lines += [f"- {s}, {m}: {v:.0%}" for (s, m), v in flagged.items()] + [""]
    path.write_text("\n".join(lines))
    return path


def write_plot(rows: list[StudyRow], config: StudyConfig, path: Path) -> Path:
    """Bars per method at the noisy level: top, mean error against the true geometry (motions
    that have one); bottom, median epipolar error of the observed points (all motions: a pure
    rotation looks as good as the rest, which is why it must be refused by other means)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    methods = list(dict.fromkeys(r.method for r in rows))
    scenes = list(dict.fromkeys(r.scene for r in rows))
    motions = list(dict.fromkeys(r.motion for r in rows))
    panels = (("truth_mean_px", [m for m in motions if m != "rotation_only"],
               "mean error vs true geometry (px)"),
              ("epipolar_median_px", motions, "median epipolar error (px)"))
    fig, axes = plt.subplots(2, len(scenes), figsize=(6 * len(scenes), 7), squeeze=False)
    width = 0.8 / len(methods)
    for row, (measure, shown, label) in enumerate(panels):
        for ax, scene in zip(axes[row], scenes, strict=True):
            for k, m in enumerate(methods):
                vals = [getattr(_find(rows, scene, motion, config.noise_px, m), measure)
                        for motion in shown]
                ax.bar(np.arange(len(shown)) + k * width, np.nan_to_num(vals, nan=0.0), width,
                       label=m)
            ax.set_xticks(np.arange(len(shown)) + 0.4 - width / 2, shown)
            ax.set_title(f"{scene}, noise {config.noise_px:g} px, "
                         f"{config.outliers:.0%} outliers")
            ax.set_ylabel(label)
    axes[0][0].legend(fontsize=8, ncol=2)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


def _find(rows: list[StudyRow], scene: str, motion: str, noise: float, method: str) -> StudyRow:
    return next(r for r in rows if (r.scene, r.motion, r.noise_px, r.method)
                == (scene, motion, noise, method))


def write_study(rows: list[StudyRow], config: StudyConfig, out_dir: Path) -> list[Path]:
    """Write ``study.md``, ``study.csv`` and ``study.png`` into ``out_dir`` (created)."""
    out_dir.mkdir(parents=True, exist_ok=True)
    return [write_markdown(rows, config, out_dir / "study.md"),
            write_csv(rows, out_dir / "study.csv"),
            write_plot(rows, config, out_dir / "study.png")]
