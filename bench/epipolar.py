"""Time features + F estimation + the pose self-check of one 640x480 pair (target: < 0.3 s).

Two pairs: the mock table scene (rendered 0.55 m above the table, 80 mm sideways baseline,
camera noise 1 grey level, exact poses) and a real one held out from every choice made in
``armstereo.epipolar`` (temple ring views 0008-0009 from tests/data, 22.5 degrees apart, the
published cameras as "recorded poses"). For each detector (Harris + NCC, SIFT, ORB) the script
times, as the median of ``--repeat`` runs in one process:

* ``match``: ``match_features`` (detection, description, matching);
* ``estimate``: ``estimate_fundamental(..., "magsac")`` on those matches;
* ``check``: the whole ``check_views`` (undistortion/prewarp when needed, matching, robust
  inliers, pose-implied F, camera-correction fit): the number the target is about.

It also reports the matches kept and the median Sampson distance of the inliers under the
pose-implied F (the self-check's measure; near 0 means the features agree with the poses).
Peers side by side in the same run: OpenCV's ``cv2.findFundamentalMat`` RANSAC on the same
matches, timed like ``estimate``.

Everything runs on one thread (OpenCV and BLAS), and both wall-clock and process CPU time are
reported: on a shared machine the CPU time is the steadier number.

    .venv/bin/python -m bench.epipolar [--repeat 7] [--markdown bench/results/epipolar.md]
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")  # before numpy loads its BLAS

import argparse  # noqa: E402
from pathlib import Path  # noqa: E402

import cv2  # noqa: E402
import numpy as np  # noqa: E402

from armstereo.camera_model import Intrinsics  # noqa: E402
from armstereo.epipolar.features import DETECTORS, match_features  # noqa: E402
from armstereo.epipolar.fundamental import (  # noqa: E402
    estimate_fundamental,
    fundamental_from_poses,
)
from armstereo.epipolar.metrics import sampson_distance  # noqa: E402
from armstereo.epipolar.selfcheck import check_views  # noqa: E402
from armstereo.transforms import invert, make_T  # noqa: E402
from bench.harness import DATA, cpu_and_wall, write_report  # noqa: E402

TEMPLE = DATA / "temple_ring"


def mock_pair():
    from armstereo.mount import CameraMount
    from armstereo.robot.arm_model import ArmModel
    from drivers.mock.scene import default_table_scene
    from drivers.mock.start_poses import table_start as mock_start_configuration

    model = ArmModel.load("ur5e", mount=CameraMount.load(None))
    T1 = model.camera_pose(mock_start_configuration(model))
    T2 = T1 @ make_T(np.eye(3), [0.08, 0.0, 0.0])
    intr = model.mount.intrinsics
    scene, rng = default_table_scene(0), np.random.default_rng(0)
    images = []
    for T in (T1, T2):
        img, _ = scene.render(T, intr)
        images.append(np.clip(np.rint(img + rng.normal(0, 1, img.shape)), 0, 255)
                      .astype(np.uint8))
    return images[0], images[1], intr, T1, intr, T2


def temple_pair():
    cams = {}
    for line in (TEMPLE / "templeSR_par.txt").read_text().splitlines()[1:]:
        name, *values = line.split()
        v = np.array(values, float)
        cams[name] = (Intrinsics(640, 480, v[:9].reshape(3, 3)),
                      invert(make_T(v[9:18].reshape(3, 3), v[18:])))
    a, b = "templeSR0008.png", "templeSR0009.png"
    return (cv2.imread(str(TEMPLE / a)), cv2.imread(str(TEMPLE / b)), cams[a][0], cams[a][1],
            cams[b][0], cams[b][1])


def timed(fn, repeat: int, cpu: list | None = None):
    """Median wall time (ms) of ``repeat`` calls and the last result; appends the median CPU
    time (ms) to ``cpu`` when given."""
    wall, cpu_s, out = cpu_and_wall(fn, repeat)
    if cpu is not None:
        cpu.append(cpu_s * 1000.0)
    return wall * 1000.0, out


def bench_pair(name: str, pair, repeat: int) -> list[str]:
    im1, im2, i1, T1, i2, T2 = pair
    F_pose = fundamental_from_poses(i1.K, i2.K, T1, T2)
    rows = []
    for det in DETECTORS:
        t_match, m = timed(lambda d=det: match_features(im1, im2, d), repeat)
        t_est, (F, mask) = timed(lambda m=m: estimate_fundamental(m.x1, m.x2, "magsac"), repeat)
        t_cv, _ = timed(lambda m=m: cv2.findFundamentalMat(m.x1, m.x2, cv2.FM_RANSAC, 1.0,
                                                           0.999), repeat)
        cpu: list[float] = []
        t_check, c = timed(lambda d=det: check_views(im1, im2, i1, T1, i2, T2, detector=d),
                           repeat, cpu)
        med_pose = float(np.median(sampson_distance(F_pose, m.x1[mask], m.x2[mask])))
        rows.append(f"| {name} | {det} | {len(m)} | {int(mask.sum())} | {t_match:.0f} | "
                    f"{t_est:.1f} | {t_cv:.1f} | {t_check:.0f} | {cpu[0]:.0f} | {med_pose:.3f} | "
                    f"{c.verdict} |")
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=7)
    ap.add_argument("--markdown", type=Path, default=None, help="also write the table here")
    args = ap.parse_args()
    check_views(*mock_pair())  # warm-up: imports, OpenCV's first-call costs
    cv2.setNumThreads(1)
    lines = ["| pair | detector | matches | inliers | match ms | MAGSAC ms | cv2 RANSAC ms | "
             "check ms | check CPU ms | median Sampson, pose F (px) | verdict |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    lines += bench_pair("mock table, 80 mm", mock_pair(), args.repeat)
    lines += bench_pair("temple 0008-0009 (held out)", temple_pair(), args.repeat)
    text = "\n".join(lines)
    write_report(text + "\n", args.markdown)


if __name__ == "__main__":
    main()
