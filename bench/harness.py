"""What every benchmark shares: timing, the data sets, the machine note and the report.

Run a benchmark from the repository root as a module, ``.venv/bin/python -m bench.<name>``
(``bench/`` is a package, so the scripts import this module without path tricks); results go
to ``bench/results/``.

* Timing: :func:`timed` (one call), :func:`median_time` (repeats after a warm-up),
  :func:`best_time` (the least of some calls), :func:`interleaved` (several peers run in turn,
  so each sees the same machine load), :func:`cpu_and_wall` (both clocks); :func:`set_threads`
  for OpenCV and numba together; :func:`child_command` and :func:`child_env` for a benchmark's
  own child processes.
* Data sets: :func:`middlebury_cases` (the four Middlebury v2 pairs in ``tests/data``),
  :func:`synthetic_cases` (rectified scenes rendered with exact ground truth by
  :func:`render`), both as :class:`Case`, with :func:`case_disparity` and
  :func:`case_scores` (bad-2 and the wrong answers); :func:`capture_and_score` (a mock
  capture with a believed and a true camera mount, reconstructed and scored).
* Reports: :func:`command_line` (the command that made a report), :func:`machine_note`,
  :func:`write_report` (print, and write the file when asked).
"""

from __future__ import annotations

import json
import os
import platform
import statistics
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "bench" / "results"
DATA = ROOT / "tests" / "data"
MIDDLEBURY = DATA / "middlebury"
MIDDLEBURY_NAMES = ("tsukuba", "venus", "teddy", "cones")


# ---------------------------------------------------------------------------- timing
def timed(fn: Callable[..., Any], *args: Any, clock: Callable[[], float] = time.perf_counter,
          **kwargs: Any) -> tuple[Any, float]:
    """``(fn(*args, **kwargs), seconds)`` on ``clock`` (wall by default)."""
    t0 = clock()
    out = fn(*args, **kwargs)
    return out, clock() - t0


def median_time(fn: Callable[[], Any], repeats: int, *, warmup: int = 1,
                clock: Callable[[], float] = time.perf_counter) -> tuple[float, Any]:
    """Median seconds of ``repeats`` calls of ``fn`` after ``warmup`` untimed ones, and the last
    result."""
    out = None
    for _ in range(warmup):
        out = fn()
    times = []
    for _ in range(repeats):
        out, t = timed(fn, clock=clock)
        times.append(t)
    return statistics.median(times), out


def best_time(fn: Callable[[], Any], repeats: int, *,
              clock: Callable[[], float] = time.perf_counter) -> float:
    """Least seconds of ``repeats`` calls of ``fn`` (no warm-up): the figure least touched by
    the machine's other load."""
    return min(timed(fn, clock=clock)[1] for _ in range(repeats))


def interleaved(peers: dict[str, Callable[[], Any]], repeats: int, *, warmup: int = 1,
                clock: Callable[[], float] = time.perf_counter) -> dict[str, tuple[float, Any]]:
    """Each peer's median seconds over ``repeats`` rounds and its last result; in every round
    the peers run one after the other, so a slow spell of the shared machine hits all alike.
    The first ``warmup`` rounds are not timed."""
    times: dict[str, list[float]] = {name: [] for name in peers}
    last: dict[str, Any] = {}
    for i in range(warmup + repeats):
        for name, fn in peers.items():
            last[name], t = timed(fn, clock=clock)
            if i >= warmup:
                times[name].append(t)
    return {name: (statistics.median(times[name]), last[name]) for name in peers}


def set_threads(n: int) -> None:
    """Threads for OpenCV and numba alike (as a user who calls the matchers without
    ``threads`` gets them)."""
    import numba

    cv2.setNumThreads(n)
    numba.set_num_threads(n)


def cpu_and_wall(fn: Callable[[], Any], repeats: int) -> tuple[float, float, Any]:
    """Median wall and median CPU seconds of ``repeats`` calls of ``fn`` (no warm-up: the
    caller decides), and the last result."""
    walls, cpus, out = [], [], None
    for _ in range(repeats):
        t0, c0 = time.perf_counter(), time.process_time()
        out = fn()
        walls.append(time.perf_counter() - t0)
        cpus.append(time.process_time() - c0)
    return statistics.median(walls), statistics.median(cpus), out


# ---------------------------------------------------------------------------- child processes
def child_command(module: str, *args: str) -> list[str]:
    """The command that runs benchmark ``module`` in a fresh interpreter (a cold numba cache,
    other threads); use it with :func:`child_env`. ``-P``: the working directory is not put on
    the path, so the path is exactly what :func:`child_env` says."""
    return [sys.executable, "-P", "-m", module, *args]


def child_env(env: dict[str, str] | None = None, src: str | Path | None = None) -> dict[str, str]:
    """``env`` (default: this process's) with the path a child needs: ``src`` first when given
    (another checkout whose ``armstereo`` is measured instead), then this repository (for
    ``bench``)."""
    env = dict(os.environ if env is None else env)
    parts = ([str(Path(src).resolve())] if src else []) + [str(ROOT)]
    if env.get("PYTHONPATH"):
        parts.append(env["PYTHONPATH"])
    env["PYTHONPATH"] = os.pathsep.join(parts)
    return env


# ---------------------------------------------------------------------------- reports
def command_line(module: str, argv: list[str] | None = None) -> str:
    """The command that runs benchmark ``module`` (``bench.stereo``) with ``argv`` (default:
    this process's arguments)."""
    args = sys.argv[1:] if argv is None else argv
    return " ".join([f".venv/bin/python -m {module}", *args])


def machine_note() -> str:
    """Cores, CPU and the versions that decide the numbers."""
    import numba

    cpu = platform.processor() or platform.machine()
    return (f"{os.cpu_count()} cores ({cpu}), Python {platform.python_version()}, "
            f"OpenCV {cv2.__version__}, numba {numba.__version__}, numpy {np.__version__}.")


def write_report(text: str, out: Path | str | None, *, echo: bool = True) -> None:
    """Print ``text`` (unless ``echo`` is False) and write it to ``out`` when given, making its
    folder first."""
    if echo:
        print(text)
    if out:
        out = Path(out)
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_text(text)


# ---------------------------------------------------------------------------- stereo data sets
@dataclass
class Case:
    """One rectified pair with ground truth; ``mask`` = pixels to score (non-occluded)."""

    name: str
    left: np.ndarray
    right: np.ndarray
    gt: np.ndarray
    mask: np.ndarray
    min_disparity: int
    max_disparity: int


def round_up_16(n: int) -> int:
    return -(-n // 16) * 16


def middlebury_cases(names: tuple[str, ...] = MIDDLEBURY_NAMES) -> list[Case]:
    """The Middlebury pairs; the window is the v2 range rounded up to SGBM's multiple of 16."""
    from armstereo.io.disparity import read_disparity

    cases = []
    for name in names:
        folder = MIDDLEBURY / name
        meta = json.loads((folder / "meta.json").read_text())
        gt = read_disparity(folder / meta["gt"], scale=meta["gt_scale"])
        cases.append(Case(name=name, left=cv2.imread(str(folder / meta["left"])),
                          right=cv2.imread(str(folder / meta["right"])), gt=gt,
                          mask=cv2.imread(str(folder / meta["masks"]["nonocc"]), 0) > 128,
                          min_disparity=0,
                          max_disparity=round_up_16(meta["max_disp"] + 1) - 1))
    return cases


@dataclass
class Surface:
    """A textured plane, disparity ``a + b u + c v`` over the left-image rectangle
    ``u0 <= u < u1, v0 <= v < v1`` (``u, v``: where the point would appear in the left view)."""

    a: float
    b: float
    c: float
    u0: float
    u1: float
    v0: float
    v1: float
    contrast: float = 50.0  # grey-level amplitude of the texture
    blur: float = 1.5  # Gaussian sigma (px) of the texture's noise: sets its bandwidth

    def disparity(self, u, v):
        return self.a + self.b * u + self.c * v

    def inside(self, u, v):
        return (u >= self.u0) & (u < self.u1) & (v >= self.v0) & (v < self.v1)

    def u_of_right(self, xr, v):
        """Left coordinate ``u`` of the plane point seen at right-image column ``xr``."""
        return (xr + self.a + self.c * v) / (1.0 - self.b)


def _texture(rng, shape, surf: Surface) -> np.ndarray:
    """Band-limited colour texture: blurred noise, three correlated channels, 128 +- contrast."""
    base = cv2.GaussianBlur(rng.standard_normal(shape).astype(np.float32), (0, 0), surf.blur)
    tint = cv2.GaussianBlur(rng.standard_normal(shape).astype(np.float32), (0, 0), surf.blur * 2)
    chans = []
    for w in (0.3, 0.0, -0.3):
        ch = base + w * tint
        chans.append(128.0 + surf.contrast * ch / (3.0 * ch.std() + 1e-6))
    return np.dstack(chans).astype(np.float32)


def render(surfaces: list[Surface], width: int, height: int, *, seed: int = 0,
           noise: float = 1.0, supersample: int = 3):
    """Render a rectified pair of ``surfaces`` (the nearest one wins in each view).

    Returns ``(left, right, gt, nonocc)``: BGR uint8 images, float32 left disparity at pixel
    centres and the mask of left pixels also seen in the right view.
    """
    rng = np.random.default_rng(seed)
    margin = 8
    u_lo = -margin
    u_hi = width + max(s.disparity(u, v) for s in surfaces for u in (0, width)
                       for v in (0, height)) + margin
    tex_w = int(np.ceil(u_hi - u_lo))
    textures = [_texture(rng, (height + 2 * margin, tex_w), s) for s in surfaces]

    def shade(view_x, view_y, right_view):
        best = np.full(view_x.shape, -np.inf, np.float32)
        colour = np.zeros(view_x.shape + (3,), np.float32)
        which = np.full(view_x.shape, -1, np.int32)
        for i, (s, tex) in enumerate(zip(surfaces, textures, strict=True)):
            u = s.u_of_right(view_x, view_y) if right_view else view_x
            d = s.disparity(u, view_y)
            hit = s.inside(u, view_y) & (d > best)
            if not hit.any():
                continue
            mx = (u - u_lo).astype(np.float32)
            my = (view_y + margin).astype(np.float32)
            sample = cv2.remap(tex, mx, my, cv2.INTER_CUBIC, borderMode=cv2.BORDER_REFLECT)
            colour[hit] = sample[hit]
            best[hit] = d[hit]
            which[hit] = i
        return colour, best, which

    offs = (np.arange(supersample) + 0.5) / supersample - 0.5
    sy, sx = np.meshgrid((np.arange(height)[:, None] + offs).ravel(),
                         (np.arange(width)[:, None] + offs).ravel(), indexing="ij")
    images = []
    for right_view in (False, True):
        colour, _, _ = shade(sx, sy, right_view)
        colour = cv2.resize(colour, (width, height), interpolation=cv2.INTER_AREA)
        colour += rng.normal(0.0, noise, colour.shape).astype(np.float32)
        images.append(np.clip(np.rint(colour), 0, 255).astype(np.uint8))
    cy, cx = np.mgrid[0:height, 0:width].astype(np.float64)
    _, gt, which_l = shade(cx, cy, False)
    xr = cx - gt
    _, _, which_r = shade(xr, cy, True)
    nonocc = (which_l == which_r) & (which_l >= 0) & (xr >= 0) & (xr <= width - 1)
    return images[0], images[1], gt.astype(np.float32), nonocc


def synthetic_cases() -> list[Case]:
    """Scenes with exact ground truth: Middlebury-like planes and a robot-like table scene."""
    W, H = 450, 375
    planes = [
        Surface(12.0, 0.02, 0.01, -1e9, 1e9, -1e9, 1e9),  # slanted background
        Surface(40.0, 0.0, 0.0, 60, 170, 50, 220),  # fronto-parallel box face
        Surface(22.0, 0.05, 0.0, 220, 400, 160, 330),  # slanted panel
        Surface(50.0, -0.03, 0.02, 300, 380, 40, 140, contrast=30),
    ]
    left, right, gt, mask = render(planes, W, H, seed=1)
    cases = [Case("synthetic planes", left, right, gt, mask, 0, 63)]
    # A camera 0.5 m above a table, 10 cm baseline: table disparities ~60-100 px rising toward
    # the bottom of the image, objects nearer (up to ~150 px); a weakly textured table.
    W, H = 640, 480
    table = [
        Surface(60.0, 0.0, 0.08, -1e9, 1e9, -1e9, 1e9, contrast=12, blur=2.0),
        Surface(120.0, 0.0, 0.0, 200, 330, 150, 300),  # box top
        Surface(95.0, 0.04, 0.03, 420, 560, 80, 260),  # tilted book
        Surface(140.0, -0.02, 0.0, 60, 150, 300, 420, contrast=35),
    ]
    left, right, gt, mask = render(table, W, H, seed=2)
    cases.append(Case("synthetic table 640x480", left, right, gt, mask, 48, 127))
    return cases


def case_disparity(case: Case, options: dict, threads: int) -> np.ndarray:
    """The disparity map of ``case`` with ``compute_disparity``'s ``options`` (``method``
    included) in its own window; ``threads`` goes to the Birchfield-Tomasi matcher."""
    from armstereo.reconstruct.stereo import compute_disparity

    if options.get("method", "birchfield") == "birchfield":
        options = dict(options, threads=threads)
    return compute_disparity(case.left, case.right, case.max_disparity,
                             min_disparity=case.min_disparity, **options)


def case_scores(case: Case, disp: np.ndarray) -> dict:
    """Bad-2 etc. on the non-occluded pixels right of the band ``x < min + max disparity``,
    plus the share of *answered* pixels (occluded ones included) that are off by > 2 px."""
    from armstereo.evaluation.disparity import evaluate_disparity

    band = case.min_disparity + case.max_disparity
    res = evaluate_disparity(disp, case.gt, case.mask, exclude_left=band)
    known = np.isfinite(case.gt)
    known[:, :band] = False
    answered = known & np.isfinite(disp)
    res["wrong_answers"] = float(np.mean(np.abs(disp - case.gt)[answered] > 2.0))
    return res


def stereo_cases() -> list[Case]:
    """The six pairs of the stereo benchmarks: Middlebury, then the synthetic scenes."""
    return middlebury_cases() + synthetic_cases()


# ---------------------------------------------------------------------------- mock experiments
def capture_and_score(folder: Path, believed, profile: str, seed: int) -> tuple[float, float]:
    """Capture a pair of the mock cell (``profile``, ``seed``) with the software believing the
    mount ``believed`` (the cell's camera is its own, whatever the software believes),
    reconstruct it (StereoSGBM, photometric correction from the recorded mount file) and score
    it against the mock's truth: (median |relative depth error|, median point distance to the
    true surfaces in mm)."""
    from armstereo import backends
    from armstereo.apps.demo import point_error_mm, score_reconstruction
    from armstereo.capture import CaptureSettings, plan_capture
    from armstereo.capture.run import model_metadata
    from armstereo.capture.session import capture_to_file
    from armstereo.photometric.correct import for_recording
    from armstereo.reconstruct.pipeline import reconstruct_pair
    from armstereo.recording import Recording
    from armstereo.robot.arm_model import ArmModel
    from armstereo.robot.source import choose_kinematics

    path = folder / f"{believed.name}.mcap"
    given = ArmModel.load("ur5e", mount=believed)
    arm_cfg = backends.arm_config("mock", profile=profile, seed=seed)
    cam_cfg = backends.camera_config("mock", profile=profile, seed=seed)
    with backends.build_arm("mock", arm_cfg, given) as arm:
        kinematics = choose_kinematics(given, arm, live=False)
        model = kinematics.model
        settings = CaptureSettings(baseline=0.08, direction=np.array([1.0, 0.0, 0.0]))
        plan = plan_capture(model, arm.joint_positions(), settings)
        with backends.build_camera("mock", cam_cfg, model, arm) as camera:
            capture_to_file(arm, camera, model, plan, path,
                            {**model_metadata(model), **kinematics.metadata()}, progress=None)
    recording = Recording.open(path)
    recon = reconstruct_pair(recording[0], method="sgbm",
                             photometric=for_recording(True, recording.metadata))
    depth = score_reconstruction(recon.depth_original, recording[0], swapped=recon.swapped)
    points = point_error_mm(recon.points_base, recording.metadata)
    return depth.median_abs_rel_depth_error, points["median"]
