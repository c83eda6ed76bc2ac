"""Benchmark: how many 640x480 views per second RecordingWriter records.

Each view is what the capture writes: a BGR image (PNG or JPEG), optionally the mock camera's
float32 ground-truth depth, /tf, joint states, the view event and a pair event, flushed to disk.
Images are textured like a real scene (multi-scale texture, shapes, sensor noise), panning a
little between views, so the image codecs do realistic work.

    .venv/bin/python -m bench.record [--views 60] [--quick]

Prints one row per setting: views/s (median of --repeat runs), MB per view.
"""

from __future__ import annotations

import argparse
import os
import statistics
import tempfile
from dataclasses import dataclass

import cv2
import numpy as np
from mcap.writer import CompressionType

from armstereo.camera_model import Intrinsics
from armstereo.devices import Frame
from armstereo.recording import RecordingWriter
from armstereo.recording.writer import JPEG_QUALITY, PNG_PARAMS
from armstereo.robot.arm_model import JOINT_NAMES
from armstereo.transforms import make_T, rot_x
from bench.harness import timed

WIDTH, HEIGHT = 640, 480


# PNG settings compared: the writer's default and OpenCV's explicit compression levels (which
# use zlib's default strategy and adaptive row filters).
PNG_SETTINGS = {
    "rle+avg (default)": PNG_PARAMS,
    "level 1": (cv2.IMWRITE_PNG_COMPRESSION, 1),
    "level 3": (cv2.IMWRITE_PNG_COMPRESSION, 3),
    "level 6": (cv2.IMWRITE_PNG_COMPRESSION, 6),
}


@dataclass(frozen=True)
class Setting:
    image_format: str
    png: str
    chunk: CompressionType
    depth: bool
    fsync: bool = False

    @property
    def label(self) -> str:
        fmt = f"png {self.png}" if self.image_format == "png" else f"jpeg q{JPEG_QUALITY}"
        return (f"{fmt:22s} chunks {self.chunk.name.lower():5s}"
                f"{' +depth' if self.depth else ''}{' +fsync' if self.fsync else ''}")


def textured_scene(rng: np.random.Generator, width: int, height: int) -> np.ndarray:
    """A large BGR texture: smooth colour blobs at several scales plus shapes and edges."""
    img = np.zeros((height, width, 3), np.float32)
    for cells, weight in ((4, 90.0), (16, 50.0), (64, 25.0), (256, 12.0)):
        grid = rng.uniform(-1, 1, (cells * height // width + 2, cells + 2, 3)).astype(np.float32)
        img += weight * cv2.resize(grid, (width, height), interpolation=cv2.INTER_CUBIC)
    img += 128
    for _ in range(60):
        colour = [int(c) for c in rng.integers(0, 256, 3)]
        x, y = int(rng.integers(0, width)), int(rng.integers(0, height))
        if rng.random() < 0.5:
            cv2.rectangle(img, (x, y), (x + int(rng.integers(10, 120)),
                                        y + int(rng.integers(10, 120))), colour, -1)
        else:
            cv2.circle(img, (x, y), int(rng.integers(5, 60)), colour, -1)
    return np.clip(img, 0, 255).astype(np.uint8)


def ground_truth_depth(shift_m: float) -> np.ndarray:
    """Ray-cast z-depth (float32 m) of a slightly tilted table with a sphere on it."""
    yy, xx = np.mgrid[0:HEIGHT, 0:WIDTH]
    rays = np.stack([(xx - 319.5) / 600.0, (yy - 239.5) / 600.0, np.ones(xx.shape)], axis=-1)
    normal, distance = np.array([0.05, -0.08, 1.0]), 0.55
    z = distance / (rays @ normal)
    centre, radius = np.array([0.02 - shift_m, 0.01, 0.48]), 0.06
    b = rays @ centre
    a = np.einsum("ijk,ijk->ij", rays, rays)
    disc = b * b - a * (centre @ centre - radius**2)
    hit = disc > 0
    z_sphere = np.where(hit, (b - np.sqrt(np.where(hit, disc, 0))) / a, np.inf)
    depth = np.minimum(z, z_sphere).astype(np.float32)
    depth[:, :40] = np.nan  # past the table edge: nothing hit
    return depth


def make_views(n: int, seed: int = 0) -> list[tuple[Frame, np.ndarray]]:
    """``n`` frames panning over one scene (2 px/view) with sensor noise, plus joints."""
    rng = np.random.default_rng(seed)
    scene = textured_scene(rng, WIDTH + 2 * n + 8, HEIGHT)
    views = []
    for k in range(n):
        crop = scene[:, 2 * k:2 * k + WIDTH].astype(np.float32)
        noisy = crop + rng.normal(0, 1.5, crop.shape).astype(np.float32)
        image = np.clip(noisy, 0, 255).astype(np.uint8)
        depth = ground_truth_depth(0.002 * k)
        views.append((Frame(image, 1_700_000_000_000_000_000 + k * 1_000_000_000, depth),
                      rng.uniform(-3, 3, 6)))
    return views


def run(setting: Setting, views, directory: str) -> tuple[float, float]:
    """Record ``views``; returns (views per second, MB per view)."""
    intr = Intrinsics(WIDTH, HEIGHT, [[600, 0, 319.5], [0, 600, 239.5], [0, 0, 1]])
    T_flange_camera = make_T(np.eye(3), [0, -0.07, 0.04])
    path = os.path.join(directory, "bench.mcap")

    def write() -> None:
        with RecordingWriter(path, metadata={"bench": "1"}, image_format=setting.image_format,
                             png_params=PNG_SETTINGS[setting.png],
                             chunk_compression=setting.chunk, fsync=setting.fsync) as w:
            w.write_calibration(intr, views[0][0].timestamp_ns - 1)
            for k, (frame, q) in enumerate(views):
                if not setting.depth:
                    frame = Frame(frame.image, frame.timestamp_ns)
                T_base_flange = make_T(rot_x(np.pi), [0.4 + 0.001 * k, 0.1, 0.5])
                w.write_view(k, frame, q, JOINT_NAMES, T_base_flange, T_flange_camera,
                             settle_s=0.5)
                if k:
                    w.write_pair(k - 1, k - 1, k, 0.1, 0.1, "x")

    _, elapsed = timed(write)
    return len(views) / elapsed, os.path.getsize(path) / len(views) / 1e6


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--views", type=int, default=60, help="views per run (default 60)")
    parser.add_argument("--repeat", type=int, default=3, help="runs per setting (median)")
    parser.add_argument("--quick", action="store_true", help="only the default settings")
    args = parser.parse_args()
    lz4, zstd, none = CompressionType.LZ4, CompressionType.ZSTD, CompressionType.NONE
    best = "rle+avg (default)"
    settings = [Setting("png", best, zstd, True), Setting("png", best, zstd, False),
                Setting("jpeg", best, zstd, True), Setting("jpeg", best, zstd, False)]
    if not args.quick:
        settings += [Setting("png", best, lz4, True), Setting("png", best, none, True),
                     Setting("png", best, zstd, True, fsync=True)]
        settings += [Setting("png", name, zstd, True) for name in PNG_SETTINGS if name != best]
    views = make_views(args.views)
    print(f"{len(views)} views of {WIDTH}x{HEIGHT} per run, median of {args.repeat} runs, "
          f"{os.cpu_count()} CPUs")
    print(f"{'setting':48s} {'views/s':>8s} {'MB/view':>8s}")
    with tempfile.TemporaryDirectory() as tmp:
        for setting in settings:
            results = [run(setting, views, tmp) for _ in range(args.repeat)]
            rate = statistics.median(r[0] for r in results)
            print(f"{setting.label:48s} {rate:8.1f} {results[0][1]:8.3f}")


if __name__ == "__main__":
    main()
