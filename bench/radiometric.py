"""Benchmark: the matchers when the two views differ in brightness (issue 26).

The right view of each pair with ground truth (the four Middlebury v2 pairs and the two
synthetic scenes of bench/stereo.py, plus a held-out synthetic scene) is changed the way the
radiometric evaluations of stereo costs change it: a gain, a gamma (response curve),
vignetting, a local illumination change, sensor noise, each alone and all together. Scored
side by side at one thread in the same window: Birchfield-Tomasi with the defaults, with the
defaults as they were before issue 26 (no brightness equalisation, no plain fill), with the
local normalisation option, and OpenCV's StereoSGBM. Bad-2 as bench/stereo.py scores it.

The changes in ``TUNING`` are the ones the defaults were chosen on; those in ``HELD_OUT``
(other magnitudes and places, a shadow, a darker exposure) and the held-out scene were not
looked at while choosing. Times: the defaults and SGBM on the unchanged pairs, interleaved,
median of ``--repeats`` runs after a warm-up.

Run: ``.venv/bin/python -m bench.radiometric [--repeats 7] [--out bench/results/radiometric.md]``.
"""

from __future__ import annotations

import argparse
from collections.abc import Callable

import numpy as np

from bench.harness import (
    RESULTS,
    Case,
    Surface,
    case_disparity,
    case_scores,
    command_line,
    interleaved,
    machine_note,
    render,
    set_threads,
    stereo_cases,
    write_report,
)

PEERS = {
    "Birchfield-Tomasi": dict(method="birchfield"),
    "before issue 26": dict(method="birchfield", equalize=False, plain_fill=None),
    "normalize_window=7": dict(method="birchfield", normalize_window=7),
    "StereoSGBM": dict(method="sgbm"),
}


def _u8(x: np.ndarray) -> np.ndarray:
    return np.clip(np.rint(x), 0, 255).astype(np.uint8)


def gain(k: float) -> Callable:
    return lambda img: _u8(img.astype(np.float32) * k)


def gamma(g: float) -> Callable:
    return lambda img: _u8(255.0 * (img.astype(np.float32) / 255.0) ** g)


def _radial(shape, amount: float, cx: float, cy: float) -> np.ndarray:
    H, W = shape[:2]
    y, x = np.mgrid[0:H, 0:W].astype(np.float32)
    r2 = ((x - cx * W) ** 2 + (y - cy * H) ** 2) / ((W / 2) ** 2 + (H / 2) ** 2)
    return 1 - amount * r2


def vignetting(amount: float, cx: float = 0.5, cy: float = 0.5) -> Callable:
    return lambda img: _u8(img.astype(np.float32) * _radial(img.shape, amount, cx, cy)[..., None])


def local(amount: float, cx: float, cy: float, sigma: float) -> Callable:
    """A Gaussian patch of light (amount > 0) or shadow (< 0), ``sigma`` in image widths."""
    def change(img):
        H, W = img.shape[:2]
        y, x = np.mgrid[0:H, 0:W].astype(np.float32)
        f = 1 + amount * np.exp(-((x - cx * W) ** 2 + (y - cy * H) ** 2) / (2 * (sigma * W) ** 2))
        return _u8(img.astype(np.float32) * f[..., None])
    return change


def noise(sigma: float, seed: int) -> Callable:
    def change(img):
        rng = np.random.default_rng(seed)
        return _u8(img.astype(np.float32) + rng.normal(0, sigma, img.shape).astype(np.float32))
    return change


def chain(*changes: Callable) -> Callable:
    def change(img):
        for c in changes:
            img = c(img)
        return img
    return change


def identity(img):
    return img


TUNING = {
    "unchanged": identity,
    "gain x1.25": gain(1.25),
    "gamma 0.8": gamma(0.8),
    "25 % vignetting": vignetting(0.25),
    "local light +30 %": local(0.3, 0.3, 0.4, 0.25),
    "noise 2 grey levels": noise(2.0, 0),
}
TUNING["all five"] = chain(*(TUNING[k] for k in list(TUNING)[1:]))
HELD_OUT = {
    "gain x0.8": gain(0.8),
    "gamma 1.25": gamma(1.25),
    "35 % vignetting off centre": vignetting(0.35, 0.6, 0.4),
    "shadow -25 %": local(-0.25, 0.7, 0.6, 0.2),
    "noise 4 grey levels": noise(4.0, 2),
    "exposure x0.7 + gamma 1.1 + noise 3": chain(gain(0.7), gamma(1.1), noise(3.0, 3)),
}
HELD_OUT["all held-out"] = chain(gain(0.8), gamma(1.25), vignetting(0.35, 0.6, 0.4),
                                 local(-0.25, 0.7, 0.6, 0.2), noise(4.0, 1))


def held_out_scene() -> Case:
    """A scene not used while choosing: a slanted floor, two boxes and a weakly textured
    wall panel, 512x384, disparities 20..90."""
    surfaces = [
        Surface(20.0, 0.0, 0.09, -1e9, 1e9, -1e9, 1e9, contrast=25, blur=1.8),
        Surface(70.0, 0.0, 0.0, 80, 200, 60, 200),
        Surface(55.0, 0.03, 0.0, 300, 460, 180, 330, contrast=40, blur=1.2),
        Surface(35.0, 0.0, 0.0, 230, 500, 20, 120, contrast=10, blur=3.0),
    ]
    left, right, gt, mask = render(surfaces, 512, 384, seed=11)
    return Case("held-out scene 512x384", left, right, gt, mask, 16, 95)


def changed(case: Case, change: Callable) -> Case:
    return Case(case.name, case.left, change(case.right), case.gt, case.mask,
                case.min_disparity, case.max_disparity)


def score_table(cases: list[Case], changes: dict[str, Callable]) -> tuple[list[str], dict]:
    """Per change: mean bad-2 of each peer and its worst pair's ratio to that pair's
    unchanged bad-2; returns the markdown rows and the scores (change -> peer -> list)."""
    scores: dict[str, dict[str, list[float]]] = {}
    unchanged = {name: [case_scores(c, case_disparity(c, opts, 1))["bad2"] * 100 for c in cases]
                 for name, opts in PEERS.items()}
    for label, change in changes.items():
        scores[label] = ({name: list(unchanged[name]) for name in PEERS}
                         if change is identity else {})
        if change is identity:
            continue
        for name, opts in PEERS.items():
            scores[label][name] = [case_scores(changed(c, change), case_disparity(
                changed(c, change), opts, 1))["bad2"] * 100 for c in cases]
    rows = ["| right view | " + " | ".join(f"{n} mean (worst pair / unchanged)" for n in PEERS)
            + " |", "|---|" + "---|" * len(PEERS)]
    for label, per in scores.items():
        cells = []
        for name in PEERS:
            worst = max(v / max(u, 1e-9) for v, u in zip(per[name], unchanged[name],
                                                         strict=True))
            cells.append(f"{np.mean(per[name]):.2f} ({worst:.2f}x)")
        rows.append(f"| {label} | " + " | ".join(cells) + " |")
    return rows, scores


def pair_table(cases: list[Case], scores: dict) -> list[str]:
    """Bad-2 of every pair under every change, defaults beside SGBM."""
    rows = ["| right view | " + " | ".join(c.name for c in cases) + " |",
            "|---|" + "---|" * len(cases)]
    for label, per in scores.items():
        cells = [f"{a:.2f} / {b:.2f}" for a, b in zip(per["Birchfield-Tomasi"],
                                                      per["StereoSGBM"], strict=True)]
        rows.append(f"| {label} | " + " | ".join(cells) + " |")
    return rows


def time_table(cases: list[Case], repeats: int) -> list[str]:
    rows = ["| pair | Birchfield-Tomasi ms | StereoSGBM ms | ratio |", "|---|---|---|---|"]
    for c in cases:
        runs = interleaved({n: (lambda c=c, o=PEERS[n]: case_disparity(c, o, 1))
                            for n in ("Birchfield-Tomasi", "StereoSGBM")}, repeats)
        bt, sg = (runs[n][0] * 1000 for n in ("Birchfield-Tomasi", "StereoSGBM"))
        rows.append(f"| {c.name} | {bt:.1f} | {sg:.1f} | {bt / sg:.2f} |")
    return rows


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--repeats", type=int, default=7)
    p.add_argument("--out", default=str(RESULTS / "radiometric.md"))
    args = p.parse_args()
    set_threads(1)
    cases = stereo_cases()
    everything = cases + [held_out_scene()]
    tuning_rows, tuning = score_table(cases, TUNING)
    held_rows, held = score_table(everything, {"unchanged": identity, **HELD_OUT})
    scene_rows, _ = score_table([held_out_scene()], TUNING)
    text = "\n".join([
        "# Radiometric benchmark: the matchers when the two views differ in brightness", "",
        f"Command: `{command_line('bench.radiometric')}`  ", machine_note(), "",
        "Bad-2 % (share of non-occluded pixels off by more than 2 px or without an answer, "
        "left band excluded, as bench/stereo.py); one thread each, same window. In brackets: "
        "the worst pair's ratio to its own unchanged bad-2.", "",
        "## Changes the defaults were chosen on (Middlebury + synthetic pairs)", "",
        *tuning_rows, "", "Per pair, Birchfield-Tomasi / StereoSGBM:", "",
        *pair_table(cases, tuning), "",
        "## Held out: other changes, and a scene not used while choosing", "",
        *held_rows, "", "Per pair, Birchfield-Tomasi / StereoSGBM:", "",
        *pair_table(everything, held), "",
        "## Held out: the tuning changes on the held-out scene", "", *scene_rows, "",
        "## Time, unchanged pairs, one thread", "",
        *time_table(everything, args.repeats), ""])
    write_report(text, args.out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
