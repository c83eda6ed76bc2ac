"""Benchmark: Birchfield-Tomasi (armstereo) against OpenCV StereoSGBM, one thread each.

Both matchers get the same disparity window on the four Middlebury v2 pairs (tests/data) and on
synthetic rectified scenes rendered here with exact ground truth (textured planes, slanted and
fronto-parallel, seen by two pinhole cameras; supersampled, with sensor noise). Scores: bad-2
(share of non-occluded pixels with |error| > 2 px or no answer) leaving out the left band of
width ``min_disparity + max_disparity`` where SGBM answers nothing, the median absolute error
of the answered pixels, and the median time of several runs.

Run: ``.venv/bin/python bench/stereo.py [--repeats 5] [--out bench/results/stereo.md]``.
"""

from __future__ import annotations

import argparse
import json
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

from armstereo.disparity_io import read_disparity  # noqa: E402
from armstereo.evaluation import evaluate_disparity  # noqa: E402
from armstereo.stereo import compute_disparity  # noqa: E402

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

METHODS = {
    "Birchfield-Tomasi": dict(method="birchfield"),
    "StereoSGBM": dict(method="sgbm"),
}


def run_case(case: Case, method: dict, repeats: int) -> dict:
    """Median time over ``repeats`` runs (after one warm-up) and the scores of the last run."""
    args = (case.left, case.right, case.max_disparity)
    kw = dict(min_disparity=case.min_disparity, **method)
    compute_disparity(*args, **kw)
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        disp = compute_disparity(*args, **kw)
        times.append(time.perf_counter() - t0)
    scores = evaluate_disparity(disp, case.gt, case.mask,
                                exclude_left=case.min_disparity + case.max_disparity)
    scores["time"] = statistics.median(times)
    return scores


def markdown(rows: list[tuple[Case, dict[str, dict]]], repeats: int) -> str:
    names = list(METHODS)
    head = ["pair", "size", "disparities"]
    for n in names:
        head += [f"{n} bad-2 %", f"{n} median err px", f"{n} ms"]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    sums = {n: [0.0, 0.0] for n in names}
    for case, res in rows:
        H, W = case.left.shape[:2]
        cells = [case.name, f"{W}x{H}",
                 f"{case.min_disparity}..{case.min_disparity + case.max_disparity}"]
        for n in names:
            r = res[n]
            cells += [f"{100 * r['bad2']:.2f}", f"{r['median_error']:.2f}",
                      f"{1000 * r['time']:.1f}"]
            sums[n][0] += r["bad2"] / len(rows)
            sums[n][1] += r["time"]
        lines.append("| " + " | ".join(cells) + " |")
    a, b = names
    ratio_bad = sums[a][0] / sums[b][0]
    ratio_time = sums[a][1] / sums[b][1]
    cpu = platform.processor() or platform.machine()
    return "\n".join(lines) + (
        f"\n\nAveraged bad-2: {a} {100 * sums[a][0]:.2f} %, {b} {100 * sums[b][0]:.2f} % "
        f"(ratio {ratio_bad:.2f}, target <= 1.3). Total of median times: {a} "
        f"{1000 * sums[a][1]:.0f} ms, {b} {1000 * sums[b][1]:.0f} ms (ratio {ratio_time:.2f}, "
        f"target <= 1.5).\n\nOne thread each (cv2.setNumThreads(1), numba.set_num_threads(1)); "
        f"median of {repeats} runs after a warm-up; bad-2 on non-occluded pixels with ground "
        f"truth, left band of width min+max disparity left out; {cpu}, Python "
        f"{platform.python_version()}, OpenCV {cv2.__version__}, numba {numba.__version__}.\n")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5, help="timed runs per case (median)")
    parser.add_argument("--out", type=Path, default=RESULTS, help="markdown table to write")
    args = parser.parse_args(argv)
    cv2.setNumThreads(1)
    numba.set_num_threads(1)
    rows = []
    for case in middlebury_cases() + synthetic_cases():
        res = {name: run_case(case, m, args.repeats) for name, m in METHODS.items()}
        rows.append((case, res))
        print(f"{case.name}: " + ", ".join(
            f"{n} bad-2 {100 * r['bad2']:.2f} % in {1000 * r['time']:.1f} ms"
            for n, r in res.items()), file=sys.stderr)
    table = markdown(rows, args.repeats)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text("# Stereo benchmark: Birchfield-Tomasi vs StereoSGBM\n\n" + table)
    print(table)
    return 0


if __name__ == "__main__":
    sys.exit(main())
