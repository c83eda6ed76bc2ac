"""Benchmark: Birchfield-Tomasi (armstereo) against OpenCV StereoSGBM with the same threads.

Both matchers get the same disparity window on the four Middlebury v2 pairs (tests/data) and on
synthetic rectified scenes rendered here with exact ground truth (textured planes, slanted and
fronto-parallel, seen by two pinhole cameras; supersampled, with sensor noise). Scores: bad-2
(share of non-occluded pixels with |error| > 2 px or no answer) leaving out the left band of
width ``min_disparity + max_disparity`` where SGBM answers nothing, and the median time of
several runs, the two peers interleaved. Targets (issue 14): bad-2 of Birchfield-Tomasi at most
SGBM's on each pair, time at most SGBM's. ``--variants`` also scores option sets of
``birchfield()``: the measurements behind its defaults (the real-photograph side of them is
bench/real_multiview.py).

Run: ``.venv/bin/python bench/stereo.py [--repeats 7] [--threads 1 2] [--variants]
[--out bench/results/stereo.md]``.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import cv2
import numba
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from armstereo.evaluation.disparity import evaluate_disparity  # noqa: E402
from armstereo.io.disparity import read_disparity  # noqa: E402
from armstereo.reconstruct.stereo import PAPER_OPTIONS, compute_disparity  # noqa: E402

MIDDLEBURY = ROOT / "tests" / "data" / "middlebury"
RESULTS = ROOT / "bench" / "results" / "stereo.md"


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


def middlebury_cases(names=("tsukuba", "venus", "teddy", "cones")) -> list[Case]:
    """The Middlebury pairs; the window is the v2 range rounded up to SGBM's multiple of 16."""
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


# --- synthetic scenes -----------------------------------------------------------------------

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


# --- running ----------------------------------------------------------------------------------

PEERS = {"Birchfield-Tomasi": dict(method="birchfield"), "StereoSGBM": dict(method="sgbm")}
# Options of birchfield() scored beside the defaults: the measurements behind the defaults.
PREVIOUS_DEFAULTS = dict(cost_window=(1, 1), slant_penalty=None, postprocess="paper",
                         texture_threshold=0.0, reward_texture=0.0, speckle_size=0,
                         subpixel="gradient", occlusions="nan", consensus_size=0)
VARIANTS = {
    "defaults": {},
    "before issue 14 item 2 (column_support=False, consensus_size=0)": dict(
        column_support=False, consensus_size=0),
    "column_support=False": dict(column_support=False),
    "consensus_size=0": dict(consensus_size=0),
    "consensus_size=7": dict(consensus_size=7),
    "consensus_size=11": dict(consensus_size=11),
    "texture_threshold=0, consensus_size=0 (dense, no consensus)": dict(
        texture_threshold=0.0, consensus_size=0),
    "column_smoothing=(1, 4)": dict(column_smoothing=(1, 4)),
    "column_smoothing=(0.5, 4)": dict(column_smoothing=(0.5, 4)),
    "column_smoothing=(1.5, 6)": dict(column_smoothing=(1.5, 6)),
    "column_smoothing=(2, 8)": dict(column_smoothing=(2, 8)),
    "column_smoothing=(1, 4), consensus_size=0": dict(column_smoothing=(1, 4),
                                                       consensus_size=0),
    "occlusion_penalty=15": dict(occlusion_penalty=15),
    "slant_penalty=10": dict(slant_penalty=10),
    "previous defaults (paper DP + its postprocessing + gradient sub-pixel)": PREVIOUS_DEFAULTS,
    "PAPER_OPTIONS (the paper's matcher as published)": PAPER_OPTIONS,
    "texture_threshold=0 (dense)": dict(texture_threshold=0.0),
    "texture_threshold=0, reward_texture=0": dict(texture_threshold=0.0, reward_texture=0.0),
    "texture_threshold=0.5": dict(texture_threshold=0.5),
    "cost_window=(1, 1)": dict(cost_window=(1, 1)),
    "cost_window=(3, 3)": dict(cost_window=(3, 3)),
    "cost_window=(1, 5)": dict(cost_window=(1, 5)),
    "slant_penalty=None": dict(slant_penalty=None),
    "slant_penalty=5": dict(slant_penalty=5),
    "speckle_size=0": dict(speckle_size=0),
    "postprocess=paper": dict(postprocess="paper"),
    "postprocess=none": dict(postprocess="none"),
    "subpixel=none": dict(subpixel="none"),
    "subpixel=gradient": dict(subpixel="gradient"),
    "occlusions=fill (paper's background fill)": dict(occlusions="fill"),
    "lr_check=True": dict(lr_check=True),
    "occlusion_penalty=35": dict(occlusion_penalty=35),
    "match_reward=3": dict(match_reward=3),
    "color=sum (single-pixel kernels)": dict(color="sum"),
    "prefilter=none, occlusion_margin=1 (before the Cones work)": dict(prefilter="none",
                                                                       occlusion_margin=1),
    "prefilter=none (intensities)": dict(prefilter="none"),
    "occlusion_margin=1": dict(occlusion_margin=1),
    "occlusion_margin=3": dict(occlusion_margin=3),
    "occlusion_margin=8": dict(occlusion_margin=8),
    "edge_cap=10": dict(edge_cap=10),
    "edge_cap=15": dict(edge_cap=15),
    "edge_cap=20": dict(edge_cap=20),
    "match_reward=6": dict(match_reward=6),
    "prefilter=highpass (gain 2)": dict(prefilter="highpass"),
    "prefilter=highpass, gain 1": dict(prefilter="highpass", prefilter_gain=1.0),
}


def _disparity(case: Case, options: dict, threads: int) -> np.ndarray:
    if options.get("method", "birchfield") == "birchfield":
        options = dict(options, threads=threads)
    return compute_disparity(case.left, case.right, case.max_disparity,
                             min_disparity=case.min_disparity, **options)


def scores(case: Case, disp: np.ndarray) -> dict:
    """Bad-2 etc. on the non-occluded pixels right of the band ``x < min + max disparity``,
    plus the share of *answered* pixels (occluded ones included) that are off by > 2 px."""
    band = case.min_disparity + case.max_disparity
    res = evaluate_disparity(disp, case.gt, case.mask, exclude_left=band)
    known = np.isfinite(case.gt)
    known[:, :band] = False
    answered = known & np.isfinite(disp)
    res["wrong_answers"] = float(np.mean(np.abs(disp - case.gt)[answered] > 2.0))
    return res


def run_peers(case: Case, repeats: int, threads: int) -> dict[str, dict]:
    """Both peers, interleaved run by run so that both see the same machine load; median
    time over ``repeats`` runs after one warm-up, scores of the last run."""
    times = {name: [] for name in PEERS}
    last = {}
    for i in range(repeats + 1):
        for name, options in PEERS.items():
            t0 = time.perf_counter()
            last[name] = _disparity(case, options, threads)
            if i:
                times[name].append(time.perf_counter() - t0)
    return {name: dict(scores(case, last[name]), time=statistics.median(times[name]))
            for name in PEERS}


def run_variants(cases: list[Case], threads: int) -> dict[str, dict]:
    """Averages over the cases for each option set (one timed run after a warm-up)."""
    out = {}
    for label, options in VARIANTS.items():
        rows = []
        for case in cases:
            _disparity(case, options, threads)
            t0 = time.perf_counter()
            disp = _disparity(case, options, threads)
            rows.append(dict(scores(case, disp), time=time.perf_counter() - t0))
        out[label] = {k: float(np.mean([r[k] for r in rows])) for k in
                      ("bad2", "wrong_answers", "invalid")}
        out[label]["time"] = float(sum(r["time"] for r in rows))
        print(f"  {label}: bad-2 {100 * out[label]['bad2']:.2f} %", file=sys.stderr)
    return out


def peers_table(rows: list[tuple[Case, dict[str, dict]]]) -> tuple[str, dict]:
    a, b = PEERS
    head = ["pair", "size", "disparities", f"{a} bad-2 %", f"{b} bad-2 %", f"{a} ms",
            f"{b} ms", "time ratio"]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for case, res in rows:
        H, W = case.left.shape[:2]
        lines.append("| " + " | ".join([
            case.name, f"{W}x{H}",
            f"{case.min_disparity}..{case.min_disparity + case.max_disparity}",
            f"{100 * res[a]['bad2']:.2f}", f"{100 * res[b]['bad2']:.2f}",
            f"{1000 * res[a]['time']:.1f}", f"{1000 * res[b]['time']:.1f}",
            f"{res[a]['time'] / res[b]['time']:.2f}"]) + " |")
    summary = {}
    for name in PEERS:
        summary[name] = dict(bad2=float(np.mean([r[name]["bad2"] for _, r in rows])),
                             time=float(sum(r[name]["time"] for _, r in rows)))
    summary["bad2_ratio"] = summary[a]["bad2"] / summary[b]["bad2"]
    summary["time_ratio"] = summary[a]["time"] / summary[b]["time"]
    lines.append("| " + " | ".join([
        "**average / total**", "", "", f"**{100 * summary[a]['bad2']:.2f}**",
        f"**{100 * summary[b]['bad2']:.2f}**", f"**{1000 * summary[a]['time']:.0f}**",
        f"**{1000 * summary[b]['time']:.0f}**", f"**{summary['time_ratio']:.2f}**"]) + " |")
    worse = [case.name for case, res in rows if res[a]["bad2"] > res[b]["bad2"]]
    slower = [case.name for case, res in rows if res[a]["time"] > res[b]["time"]]
    verdict = (f"Averaged bad-2 ratio {summary['bad2_ratio']:.2f}, total median time ratio "
               f"{summary['time_ratio']:.2f}. Per-pair targets (bad-2 and time at most SGBM's): "
               f"bad-2 {'met' if not worse else 'MISSED on ' + ', '.join(worse)}; time "
               f"{'met' if not slower else 'MISSED on ' + ', '.join(slower)}.")
    return "\n".join(lines) + "\n\n" + verdict + "\n", summary


def variants_table(res: dict[str, dict]) -> str:
    lines = ["| birchfield() options | bad-2 % | wrong answers % | no answer % | total ms |",
             "|---|---|---|---|---|"]
    for label, r in res.items():
        lines.append(f"| {label} | {100 * r['bad2']:.2f} | {100 * r['wrong_answers']:.2f} | "
                     f"{100 * r['invalid']:.2f} | {1000 * r['time']:.0f} |")
    return "\n".join(lines) + "\n"


def set_threads(n: int) -> None:
    cv2.setNumThreads(n)
    numba.set_num_threads(n)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=7, help="timed runs per case (median)")
    parser.add_argument("--threads", type=int, nargs="+", default=[1],
                        help="thread counts to run the peers with (default 1; e.g. 1 2)")
    parser.add_argument("--variants", action="store_true",
                        help="also score birchfield() option sets (one thread)")
    parser.add_argument("--out", type=Path, default=RESULTS, help="markdown file to write")
    args = parser.parse_args(argv)
    cases = middlebury_cases() + synthetic_cases()
    parts = [f"# Stereo benchmark: Birchfield-Tomasi vs StereoSGBM\n\n"
             f"Command: `.venv/bin/python bench/stereo.py {' '.join(argv or sys.argv[1:])}`"
             f"  \nDate: {time.strftime('%Y-%m-%d')}; {machine_note()}\n"]
    for n in args.threads:
        set_threads(n)
        rows = []
        for case in cases:
            res = run_peers(case, args.repeats, n)
            rows.append((case, res))
            print(f"{n} thread(s) {case.name}: " + ", ".join(
                f"{k} bad-2 {100 * r['bad2']:.2f} % in {1000 * r['time']:.1f} ms"
                for k, r in res.items()), file=sys.stderr)
        table, _ = peers_table(rows)
        parts.append(f"## {n} thread{'s' if n > 1 else ''} each\n\n{table}")
    if args.variants:
        set_threads(1)
        print("birchfield() options:", file=sys.stderr)
        parts.append("## birchfield() options (one thread, averages over the six pairs)\n\n"
                     + variants_table(run_variants(cases, 1)))
    parts.append(NOTES)
    text = "\n".join(parts)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(text)
    print(text)
    return 0


def machine_note() -> str:
    cpu = platform.processor() or platform.machine()
    return (f"{os.cpu_count()} cores ({cpu}), Python {platform.python_version()}, "
            f"OpenCV {cv2.__version__}, numba {numba.__version__}, numpy {np.__version__}.")


NOTES = """
Scoring: bad-2 = share of non-occluded pixels with ground truth whose error exceeds 2 px or
that have no answer, leaving out the left band `x < min + max disparity` (where SGBM answers
nothing); averaged over the pairs. "Wrong answers" = share of the answered pixels with ground
truth (occluded ones included) whose error exceeds 2 px. Times: median over the runs after one
warm-up, both peers interleaved run by run; threads set with `cv2.setNumThreads` and
`numba.set_num_threads` (birchfield matches chunks of rows on that many threads and runs the
other steps on strips of rows; scaling in bench/results/stereo_scaling.md). Same disparity
window for both: the Middlebury v2 range rounded up to SGBM's multiple of 16. Option sets:
one timed run each, so their times are rough. The machine is shared: times move by 10-20 %
from run to run, the ratios much less. Whether the matcher's threads slow the stages after
it: bench/stereo_threads.py (stereo_threads.md).
"""


if __name__ == "__main__":
    sys.exit(main())
