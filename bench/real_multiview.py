"""Benchmark: Birchfield-Tomasi and StereoSGBM on calibrated real photographs, pose-based path.

Data: Middlebury's multi-view rings ``templeSparseRing`` and ``dinoSparseRing`` (640x480 colour
views with exact cameras ``P = K [R | t]``, world in metres; Seitz et al., CVPR 2006). Give the
folder that holds both ring folders with ``--data DIR`` or the environment variable
``ARMSTEREO_MVS_DATA``; nothing is downloaded.

Every neighbouring pair of a ring (viewing directions 5-25 deg apart) goes through the same path
as a robot scan: Fusiello rectification from the given poses (``rectify_pair``, depth range
from the object's known bounding box, so far = disparity 0), matching, triangulation into the
world frame (``point_cloud``). Both matchers get the same window (``max_disparity`` rounded up
to SGBM's multiple of 16) and run at one thread, interleaved. Scores per pair:

- ``outside %``: share of the pair's points outside the object's bounding box (+ 5 mm);
- ``density %``: points inside the box per rectified left pixel whose ray meets the box;
- ``sparse bad-2 %``: SIFT features matched between the two original views (ratio test,
  epipolar distance < 1 px from the known cameras, triangulated inside the box with < 1 px
  reprojection error) are an independent reference; share of them where the dense disparity
  is missing or more than 2 px off (``sparse miss %``: only the missing ones);
- cross-pair distance: two pairs that share a view reconstruct surfaces seen in that view; for
  every point of one cloud the distance to the nearest point of the other (both directions),
  median and 90th percentile in mm;
- ``ms``: median matching time (``compute_disparity``) of ``--repeats`` runs after a warm-up.

Pairs whose two views both lie in the held-out halves (temple views 9-16, dino views 9-16) and
cross-pair comparisons whose three views all do were not used for tuning; they are reported
separately. Run:
``.venv/bin/python -m bench.real_multiview --data DIR [--repeats 3] [--out FILE] [--variant
LABEL=JSON ...]``.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import cv2
import numba
import numpy as np

from armstereo.camera_model import Intrinsics
from armstereo.reconstruct.rectify import rectified_geometry, rectify_pair
from armstereo.reconstruct.stereo import compute_disparity
from armstereo.reconstruct.triangulate import point_cloud
from armstereo.transforms import make_T
from bench.harness import RESULTS as BENCH_RESULTS
from bench.harness import interleaved, write_report

DATA_ENV = "ARMSTEREO_MVS_DATA"
RESULTS = BENCH_RESULTS / "real_multiview.md"

# Tight bounding boxes (world frame, m) from the data sets' original READMEs.
RINGS = {
    "temple": ("templeSparseRing", "templeSR",
               ((-0.073568, 0.021728, -0.012445), (0.028855, 0.181892, 0.062736))),
    "dino": ("dinoSparseRing", "dinoSR",
             ((-0.061897, -0.018874, -0.057845), (0.010897, 0.068227, 0.015495))),
}
HELD_OUT_FROM = 9  # views with this number and above form the held-out half of each ring
PAIR_ANGLE_DEG = (5.0, 25.0)  # viewing directions this far apart count as neighbours
BOX_MARGIN = 0.005  # m: a point this far outside the tight box still counts as inside
DEPTH_MARGIN = 0.03  # relative margin on the box's depth range
SPARSE_RATIO = 0.75  # Lowe's ratio test
SPARSE_EPIPOLAR_PX = 1.0
SPARSE_REPROJECTION_PX = 1.0
BAD_PX = 2.0
QUERY_SAMPLE = 20000  # points per cloud whose nearest neighbour is looked up
PEERS = {"Birchfield-Tomasi": dict(method="birchfield"), "StereoSGBM": dict(method="sgbm")}


@dataclass
class View:
    name: str
    number: int
    image: np.ndarray
    K: np.ndarray
    T_world_cam: np.ndarray  # camera (OpenCV optical) pose in the world frame

    @property
    def P(self) -> np.ndarray:
        T = np.linalg.inv(self.T_world_cam)
        return self.K @ T[:3, :]


@dataclass
class Pair:
    ring: str
    a: View
    b: View
    box: tuple[np.ndarray, np.ndarray]
    held_out: bool


def load_ring(data: Path, ring: str) -> tuple[list[View], tuple[np.ndarray, np.ndarray]]:
    folder, prefix, box = RINGS[ring]
    lines = (data / folder / f"{prefix}_par.txt").read_text().split("\n")[1:]
    views = []
    for line in lines:
        parts = line.split()
        if not parts:
            continue
        vals = np.array(parts[1:], float)
        K, R, t = vals[:9].reshape(3, 3), vals[9:18].reshape(3, 3), vals[18:21]
        U, _, Vt = np.linalg.svd(R)  # the files print R with ~1e-6 precision
        T_cam_world = make_T(U @ Vt, t)
        image = cv2.imread(str(data / folder / parts[0]), cv2.IMREAD_COLOR)
        number = int(parts[0][len(prefix):len(prefix) + 4])
        views.append(View(parts[0], number, image, K, np.linalg.inv(T_cam_world)))
    return views, (np.array(box[0]), np.array(box[1]))


def ring_pairs(ring: str, views: list[View], box) -> list[Pair]:
    centre = 0.5 * (box[0] + box[1])
    dirs = [(v.T_world_cam[:3, 3] - centre) / np.linalg.norm(v.T_world_cam[:3, 3] - centre)
            for v in views]
    pairs = []
    for i in range(len(views)):
        for j in range(i + 1, len(views)):
            angle = np.degrees(np.arccos(np.clip(dirs[i] @ dirs[j], -1, 1)))
            if PAIR_ANGLE_DEG[0] <= angle <= PAIR_ANGLE_DEG[1]:
                held = min(views[i].number, views[j].number) >= HELD_OUT_FROM
                pairs.append(Pair(ring, views[i], views[j], box, held))
    return pairs


def box_corners(box) -> np.ndarray:
    lo, hi = box
    return np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1])
                     for z in (lo[2], hi[2])])


def rectify(pair: Pair):
    """Rectified pair with far end of the box at disparity 0, and the matcher's window."""
    intr = [Intrinsics(v.image.shape[1], v.image.shape[0], v.K, np.zeros(5))
            for v in (pair.a, pair.b)]
    geom, _ = rectified_geometry(intr[0], pair.a.T_world_cam, intr[1], pair.b.T_world_cam)
    z = (geom.R_rect @ (box_corners(pair.box) - geom.c_left).T)[2]
    near, far = z.min() * (1 - DEPTH_MARGIN), z.max() * (1 + DEPTH_MARGIN)
    rect = rectify_pair(pair.a.image, pair.b.image, pair.a.K, None, pair.a.T_world_cam,
                        pair.b.K, None, pair.b.T_world_cam, depth_range=(near, far))
    g = rect.geometry
    span = g.fx * g.baseline * (1 / near - 1 / far)
    max_disparity = int(-(-(int(np.ceil(span)) + 1) // 16) * 16) - 1
    max_disparity = min(max_disparity, g.size[0] - 2)
    return rect, max_disparity


def inside_box(points: np.ndarray, box, margin: float = BOX_MARGIN) -> np.ndarray:
    return np.all((points >= box[0] - margin) & (points <= box[1] + margin), axis=1)


def box_pixels(rect, box) -> np.ndarray:
    """Rectified left pixels whose ray meets the box (convex hull of its projected corners)."""
    g = rect.geometry
    pts = (g.R_rect @ (box_corners(box) - g.c_left).T).T
    uv = (g.K_left @ pts.T).T
    uv = uv[:, :2] / uv[:, 2:]
    hull = cv2.convexHull(np.round(uv).astype(np.int32))
    mask = np.zeros((g.size[1], g.size[0]), np.uint8)
    cv2.fillConvexPoly(mask, hull, 1)
    return (mask > 0) & rect.left_mask


# --- independent sparse reference ------------------------------------------------------------

def sparse_reference(pair: Pair, rect) -> np.ndarray:
    """(N, 3) rectified ``(u_left, v_left, disparity)`` of triangulated SIFT matches."""
    sift = cv2.SIFT_create()
    grey = [cv2.cvtColor(v.image, cv2.COLOR_BGR2GRAY) for v in (pair.a, pair.b)]
    (ka, da), (kb, db) = (sift.detectAndCompute(g, None) for g in grey)
    if da is None or db is None:
        return np.zeros((0, 3))
    knn = cv2.BFMatcher(cv2.NORM_L2).knnMatch(da, db, k=2)
    good = [m[0] for m in knn if len(m) == 2 and m[0].distance < SPARSE_RATIO * m[1].distance]
    if not good:
        return np.zeros((0, 3))
    pa = np.float64([ka[m.queryIdx].pt for m in good])
    pb = np.float64([kb[m.trainIdx].pt for m in good])
    Pa, Pb = pair.a.P, pair.b.P
    F = fundamental(Pa, Pb)
    ha, hb = np.c_[pa, np.ones(len(pa))], np.c_[pb, np.ones(len(pb))]
    lines_b = ha @ F.T  # epipolar lines in b
    dist = np.abs(np.sum(lines_b * hb, axis=1)) / np.hypot(lines_b[:, 0], lines_b[:, 1])
    keep = dist < SPARSE_EPIPOLAR_PX
    pa, pb = pa[keep], pb[keep]
    X = cv2.triangulatePoints(Pa, Pb, pa.T, pb.T)
    X = (X[:3] / X[3]).T
    err = np.maximum(reprojection(Pa, X, pa), reprojection(Pb, X, pb))
    keep = inside_box(X, pair.box, 0.0) & (err < SPARSE_REPROJECTION_PX)
    pa, pb = pa[keep], pb[keep]
    if rect.swapped:
        pa, pb = pb, pa
    H1, H2 = rect.rectification.H1, rect.rectification.H2
    ul, ur = dehom(H1, pa), dehom(H2, pb)
    return np.c_[ul, ul[:, 0] - ur[:, 0]]


def fundamental(Pa: np.ndarray, Pb: np.ndarray) -> np.ndarray:
    """F with ``xb^T F xa = 0`` from two projection matrices."""
    c = np.linalg.svd(Pa)[2][-1]
    e = Pb @ c
    ex = np.array([[0, -e[2], e[1]], [e[2], 0, -e[0]], [-e[1], e[0], 0]])
    return ex @ Pb @ np.linalg.pinv(Pa)


def reprojection(P, X, px) -> np.ndarray:
    h = (P @ np.c_[X, np.ones(len(X))].T).T
    return np.linalg.norm(h[:, :2] / h[:, 2:] - px, axis=1)


def dehom(H, pts) -> np.ndarray:
    h = (H @ np.c_[pts, np.ones(len(pts))].T).T
    return h[:, :2] / h[:, 2:]


def sparse_scores(disp: np.ndarray, ref: np.ndarray) -> dict:
    u = np.rint(ref[:, 0]).astype(int)
    v = np.rint(ref[:, 1]).astype(int)
    ok = (u >= 0) & (v >= 0) & (u < disp.shape[1]) & (v < disp.shape[0])
    d = np.full(len(ref), np.nan)
    d[ok] = disp[v[ok], u[ok]]
    miss = ~np.isfinite(d)
    with np.errstate(invalid="ignore"):
        bad = miss | (np.abs(d - ref[:, 2]) > BAD_PX)
    return dict(sparse_n=len(ref), sparse_bad2=float(bad.mean()) if len(ref) else np.nan,
                sparse_miss=float(miss.mean()) if len(ref) else np.nan)


# --- running -------------------------------------------------------------------------------

def match(rect, max_disparity: int, options: dict) -> np.ndarray:
    opts = dict(options)
    if opts.get("method", "birchfield") == "birchfield":
        opts.setdefault("threads", 1)
    return compute_disparity(rect.left, rect.right, max_disparity, left_mask=rect.left_mask,
                             right_mask=rect.right_mask, **opts)


def run_pair(pair: Pair, peers: dict[str, dict], repeats: int) -> dict:
    rect, nmax = rectify(pair)
    ref = sparse_reference(pair, rect)
    pix = box_pixels(rect, pair.box)
    # one warm-up round, then ``repeats`` timed rounds (or one timed round when 0)
    got = interleaved({name: (lambda o=options: match(rect, nmax, o))
                       for name, options in peers.items()},
                      max(repeats, 1), warmup=1 if repeats else 0)
    times = {name: t for name, (t, _) in got.items()}
    disp = {name: d for name, (_, d) in got.items()}
    out = dict(size=rect.geometry.size, window=nmax, clouds={}, scores={})
    for name in peers:
        pts, _ = point_cloud(disp[name], rect.geometry, rect.left, mask=rect.left_mask)
        inside = inside_box(pts.astype(np.float64), pair.box)
        out["clouds"][name] = pts
        out["scores"][name] = dict(
            points=len(pts), outside=float(1 - inside.mean()) if len(pts) else np.nan,
            density=float(inside.sum() / max(1, pix.sum())),
            time=times[name], **sparse_scores(disp[name], ref))
        out.setdefault("disp", {})[name] = disp[name]
    out["rect"] = rect
    return out


def nearest_distances(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distance (m) from (a seeded sample of at most QUERY_SAMPLE) points of ``a`` to their
    nearest neighbours in ``b`` (KD-tree)."""
    if len(a) == 0 or len(b) == 0:
        return np.zeros(0)
    if len(a) > QUERY_SAMPLE:
        a = a[np.random.default_rng(0).choice(len(a), QUERY_SAMPLE, replace=False)]
    index = cv2.flann_Index(np.ascontiguousarray(b, np.float32), dict(algorithm=1, trees=4))
    _, d2 = index.knnSearch(np.ascontiguousarray(a, np.float32), 1, params=dict(checks=64))
    return np.sqrt(d2[:, 0])


def cross_pairs(pairs: list[Pair]) -> list[tuple[int, int, bool]]:
    """Index pairs (i, j) of pairs that share a view; flag: all three views held out."""
    out = []
    for i, p in enumerate(pairs):
        for j in range(i + 1, len(pairs)):
            q = pairs[j]
            if p.ring != q.ring:
                continue
            names = {p.a.name, p.b.name}
            other = {q.a.name, q.b.name}
            if len(names & other) == 1:
                nums = {v.number for v in (p.a, p.b, q.a, q.b)}
                out.append((i, j, min(nums) >= HELD_OUT_FROM))
    return out


def summarise(results, pairs, crosses, peers, held: bool) -> str:
    names = list(peers)
    sel = [i for i, p in enumerate(pairs) if p.held_out == held]
    lines = ["| pair | window | " + " | ".join(
        f"{n} {k}" for k in ("outside %", "density %", "sparse bad-2 %", "ms") for n in names)
        + " |", "|---|---|" + "---|" * (4 * len(names))]
    for i in sel:
        p, r = pairs[i], results[i]
        s = r["scores"]
        cells = []
        for key, scale, fmt in (("outside", 100, ".1f"), ("density", 100, ".1f"),
                                ("sparse_bad2", 100, ".1f"), ("time", 1000, ".0f")):
            cells += [format(scale * s[n][key], fmt) for n in names]
        lines.append(f"| {p.ring} {p.a.number:02d}-{p.b.number:02d} | 0..{r['window']} | "
                     + " | ".join(cells) + " |")
    tot = {n: {k: float(np.mean([results[i]["scores"][n][k] for i in sel]))
               for k in ("outside", "density", "sparse_bad2")} for n in names}
    for n in names:
        tot[n]["time"] = float(sum(results[i]["scores"][n]["time"] for i in sel))
    cells = []
    for key, scale, fmt in (("outside", 100, ".1f"), ("density", 100, ".1f"),
                            ("sparse_bad2", 100, ".1f"), ("time", 1000, ".0f")):
        cells += [f"**{format(scale * tot[n][key], fmt)}**" for n in names]
    lines.append("| **mean (time: total)** | | " + " | ".join(cells) + " |")
    text = "\n".join(lines) + "\n\n"
    # cross-pair distances, per ring
    rows = ["| ring | comparisons | " + " | ".join(
        f"{n} {k}" for k in ("median mm", "p90 mm") for n in names) + " |",
        "|---|---|" + "---|" * (2 * len(names))]
    for ring in sorted({p.ring for p in pairs}):
        sel_c = [(i, j) for i, j, h in crosses if h == held and pairs[i].ring == ring]
        if not sel_c:
            continue
        cells_m, cells_p = [], []
        for n in names:
            dists = np.concatenate([np.concatenate([
                nearest_distances(results[i]["clouds"][n], results[j]["clouds"][n]),
                nearest_distances(results[j]["clouds"][n], results[i]["clouds"][n])])
                for i, j in sel_c])
            cells_m.append(f"{1000 * np.median(dists):.2f}")
            cells_p.append(f"{1000 * np.percentile(dists, 90):.2f}")
        rows.append(f"| {ring} | {len(sel_c)} | " + " | ".join(cells_m + cells_p) + " |")
    text += "\n".join(rows) + "\n"
    return text


def parse_variants(items: list[str]) -> dict[str, dict]:
    peers = dict(PEERS)
    for item in items:
        label, _, options = item.partition("=")
        peers[label] = dict(json.loads(options), method="birchfield")
    return peers


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=os.environ.get(DATA_ENV),
                        help=f"folder holding templeSparseRing/ and dinoSparseRing/ "
                        f"(default: ${DATA_ENV})")
    parser.add_argument("--repeats", type=int, default=3,
                        help="timed runs per pair after a warm-up (median); 0: one run, "
                        "untimed in effect (includes compilation)")
    parser.add_argument("--rings", nargs="+", default=list(RINGS), choices=list(RINGS))
    parser.add_argument("--variant", action="append", default=[], metavar="LABEL=JSON",
                        help="also run birchfield() with these options, e.g. "
                        "'plain={\"postprocess\": true}'")
    parser.add_argument("--held-out", action="store_true", help="also run the held-out pairs")
    parser.add_argument("--only-held-out", action="store_true", help="run the held-out pairs only")
    parser.add_argument("--limit", type=int, default=None, help="at most this many pairs per ring")
    parser.add_argument("--save", type=Path, default=None,
                        help="write each pair's rectified left image and disparities here")
    parser.add_argument("--out", type=Path, default=None, help="markdown file to write")
    args = parser.parse_args(argv)
    if args.data is None:
        parser.error(f"give --data DIR or set {DATA_ENV}")
    cv2.setNumThreads(1)
    numba.set_num_threads(1)
    peers = parse_variants(args.variant)
    pairs = []
    for ring in args.rings:
        views, box = load_ring(args.data, ring)
        ring = ring_pairs(ring, views, box)
        if args.only_held_out:
            ring = [p for p in ring if p.held_out]
        elif not args.held_out:
            ring = [p for p in ring if not p.held_out]
        pairs += ring[:args.limit]
    results = []
    for p in pairs:
        res = run_pair(p, peers, args.repeats)
        results.append(res)
        print(f"{p.ring} {p.a.number:02d}-{p.b.number:02d}: " + ", ".join(
            f"{n} out {100 * s['outside']:.1f} % dens {100 * s['density']:.1f} % sparse "
            f"{100 * s['sparse_bad2']:.1f} % {1000 * s['time']:.0f} ms"
            for n, s in res["scores"].items()), file=sys.stderr)
        if args.save:
            save_pair(args.save, p, res)
    crosses = cross_pairs(pairs)
    given = list(argv if argv is not None else sys.argv[1:])
    # the data folder is the reader's own (the photographs are not in the repository)
    shown = ["DIR" if i and given[i - 1] == "--data" else a for i, a in enumerate(given)]
    parts = [f"# Real multi-view photographs: Birchfield-Tomasi vs StereoSGBM\n\n"
             f"Command: `.venv/bin/python -m bench.real_multiview {' '.join(shown)}`  \n"
             f"Date: {time.strftime('%Y-%m-%d')}; one thread each. Variants: "
             + "; ".join(f"`{k}` = {json.dumps(v)}" for k, v in peers.items()) + "\n",
             ]
    if not args.only_held_out:
        parts.append("## Tuning pairs\n\n" + summarise(results, pairs, crosses, peers, False))
    if args.held_out or args.only_held_out:
        parts.append("## Held-out pairs (not used for tuning)\n\n"
                     + summarise(results, pairs, crosses, peers, True))
    parts.append(NOTES)
    text = "\n".join(parts)
    write_report(text, args.out)
    return 0


def save_pair(folder: Path, pair: Pair, res: dict) -> None:
    folder.mkdir(parents=True, exist_ok=True)
    stem = f"{pair.ring}{pair.a.number:02d}-{pair.b.number:02d}"
    cv2.imwrite(str(folder / f"{stem}_left.png"), res["rect"].left)
    for name, d in res["disp"].items():
        vis = np.zeros(d.shape + (3,), np.uint8)
        ok = np.isfinite(d)
        scaled = np.zeros(d.shape, np.uint8)
        scaled[ok] = np.clip(255 * d[ok] / max(1, res["window"]), 0, 255).astype(np.uint8)
        vis = cv2.applyColorMap(scaled, cv2.COLORMAP_TURBO)
        vis[~ok] = 0
        cv2.imwrite(str(folder / f"{stem}_{name.replace(' ', '_')}.png"), vis)


NOTES = """
Scores (see the module doc of bench/real_multiview.py): `outside %` = share of a pair's points
outside the object's tight bounding box + 5 mm; `density %` = points inside the box per
rectified left pixel whose ray meets the box; `sparse bad-2 %` = share of independently
triangulated SIFT matches where the dense disparity is missing or off by more than 2 px;
cross-pair distance = nearest-neighbour distance between the clouds of two pairs that share a
view, both directions pooled (mm). Depth per pixel of disparity is about 1 mm (temple) and
0.5 mm (dino). Times: median matching time after a warm-up, the peers interleaved, one thread;
the machine is shared, so only the ratios of the same run mean something.
"""


if __name__ == "__main__":
    sys.exit(main())
