"""Open3D's TSDF (tensor VoxelBlockGrid) on the same depth frames: the peer for bench/fusion.py.

Runs in an interpreter that has open3d (kept out of the project's environment: ~600 MB and a
system libusb; see docs/fusion.md)::

    python -m venv /tmp/o3d && /tmp/o3d/bin/pip install open3d-cpu   # + apt libusb-1.0-0
    /tmp/o3d/bin/python -m bench.open3d_peer FRAMES.npz OUT.npz [--no-half-pixel]

FRAMES.npz (written by bench/fusion.py): ``depth_<k>`` (H, W) float32 m (NaN = none),
``K_<k>`` 3x3, ``T_<k>`` 4x4 T_base_camera, ``count``, ``voxel``, ``trunc``, ``roi`` (6,).
OUT.npz: ``vertices`` (N, 3), ``faces`` (M, 3) of the mesh cropped to the ROI, and the
timings ``integrate_s`` and ``extract_s``.

Open3D truncates the projected pixel coordinate (pixel u covers [u, u+1)), so depth maps with
OpenCV's pixel centres at integer u are integrated with cx + 0.5, cy + 0.5; ``--no-half-pixel``
leaves them as they are (to show the bias). ``--weight-threshold`` (default 0.5: voxels seen
once are kept, Open3D compares with ">").
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import open3d as o3d
import open3d.core as o3c

BLOCK_RESOLUTION = 16
DEPTH_MAX_M = 3.0
# Open3D keeps voxels whose weight is strictly greater than the threshold: 0.5 keeps surfaces
# seen once (1.0, as often advised, drops them; its default 3.0 drops everything seen < 4 times)
WEIGHT_THRESHOLD = 0.5


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("frames")
    ap.add_argument("out")
    ap.add_argument("--no-half-pixel", action="store_true")
    ap.add_argument("--weight-threshold", type=float, default=WEIGHT_THRESHOLD)
    args = ap.parse_args()
    data = np.load(args.frames)
    voxel, trunc = float(data["voxel"]), float(data["trunc"])
    roi = data["roi"]
    size = roi[1::2] - roi[0::2]
    blocks = int(np.prod(np.ceil(size / (voxel * BLOCK_RESOLUTION)) + 2))
    vbg = o3d.t.geometry.VoxelBlockGrid(
        attr_names=("tsdf", "weight"), attr_dtypes=(o3c.float32, o3c.float32),
        attr_channels=((1), (1)), voxel_size=voxel, block_resolution=BLOCK_RESOLUTION,
        block_count=max(blocks, 1000), device=o3c.Device("CPU:0"))
    mult = trunc / voxel
    t0 = time.perf_counter()
    for k in range(int(data["count"])):
        depth = np.nan_to_num(data[f"depth_{k}"], nan=0.0).astype(np.float32)
        K = data[f"K_{k}"].astype(np.float64).copy()
        if not args.no_half_pixel:
            K[0, 2] += 0.5
            K[1, 2] += 0.5
        extrinsic = o3c.Tensor(np.linalg.inv(data[f"T_{k}"]), o3c.float64)
        img = o3d.t.geometry.Image(o3c.Tensor(depth))
        intr = o3c.Tensor(K, o3c.float64)
        bc = vbg.compute_unique_block_coordinates(img, intr, extrinsic, 1.0, DEPTH_MAX_M, mult)
        vbg.integrate(bc, img, intr, extrinsic, 1.0, DEPTH_MAX_M, mult)
    integrate_s = time.perf_counter() - t0
    t0 = time.perf_counter()
    mesh = vbg.extract_triangle_mesh(weight_threshold=args.weight_threshold)
    extract_s = time.perf_counter() - t0
    v = mesh.vertex.positions.numpy().astype(np.float64)
    f = mesh.triangle.indices.numpy().astype(np.int64)
    lo, hi = roi[0::2], roi[1::2]
    inside = np.all((v >= lo) & (v <= hi), axis=1)
    f = f[inside[f].all(axis=1)]
    np.savez(args.out, vertices=v, faces=f, integrate_s=integrate_s, extract_s=extract_s)


if __name__ == "__main__":
    main()
