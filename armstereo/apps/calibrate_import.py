"""``armstereo calibrate --images GLOB --poses FILE``: calibrate data recorded elsewhere.

A folder of images and a file of arm poses (:mod:`armstereo.calibration.pose_import`) are
matched (by image name when the pose file names images, else in order), written into an
ordinary calibration recording (MCAP: each image with its flange pose on /tf, its joints when
the poses were joints, the held intrinsics on the calibration topic), and that recording is
calibrated exactly as a live session's is (:func:`armstereo.apps.calibrate.finish`), so
``calibrate --from`` on it afterwards gives the same mount. Moves nothing.
"""

from __future__ import annotations

import glob
import json
import re
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from armstereo.calibration.board import Board
from armstereo.calibration.pose_import import PoseFile, PoseRecord, flange_pose, read_poses
from armstereo.calibration.poses import rotmat
from armstereo.calibration.session import (
    IMPORT_IMAGES_KEY,
    IMPORT_POSE_KIND_KEY,
    IMPORT_POSES_KEY,
    IMPORT_SOURCE,
    INTRINSICS_KEY,
    POSE_SOURCE_KEY,
    calibration_metadata,
)
from armstereo.camera_model import Intrinsics
from armstereo.errors import ConfigError
from armstereo.frame import Frame
from armstereo.robot.arm_model import ArmModel
from armstereo.transforms import make_T

IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".pgm", ".ppm")
VIEW_PERIOD_NS = 1_000_000_000  # imported views get timestamps 1 s apart (order only)


@dataclass
class ImportedViews:
    """Matched views: image paths, images (uint8), flange poses (base frame), joints (rad,
    or None per view for pose files) and the pose file."""

    paths: list[Path]
    images: list[np.ndarray]
    flanges: list[np.ndarray]
    joints: list[np.ndarray] | None
    poses: PoseFile


def find_images(pattern: str) -> list[Path]:
    """Image files matching ``pattern`` (a glob, or a directory: every image in it), in
    natural order (``img2`` before ``img10``); ConfigError when there is none."""
    p = Path(pattern)
    found = sorted(p.iterdir()) if p.is_dir() else [Path(x) for x in glob.glob(pattern)]
    images = [f for f in found if f.is_file() and f.suffix.lower() in IMAGE_SUFFIXES]
    if not images:
        raise ConfigError(f"--images {pattern!r} matches no image file "
                          f"({', '.join(IMAGE_SUFFIXES)})")
    return sorted(images, key=_natural_key)


def _natural_key(path: Path) -> list:
    return [int(t) if t.isdigit() else t.lower() for t in re.split(r"(\d+)", path.name)]


def parse_tcp_offset(text: str | None) -> np.ndarray | None:
    """``--tcp x,y,z,rx,ry,rz`` (m, rad: the controller's TCP offset) as T_flange_tcp."""
    if not text:
        return None
    try:
        v = [float(x) for x in text.replace(" ", "").split(",")]
    except ValueError:
        v = []
    if len(v) != 6 or not all(np.isfinite(v)):
        raise ConfigError(f"--tcp must be x,y,z,rx,ry,rz (m, rad), got {text!r}")
    return make_T(rotmat(v[3:]), v[:3])


def import_views(images: str, poses: str | Path, *, model: ArmModel | None = None,
                 pose_format: str = "auto",
                 T_flange_tcp: np.ndarray | None = None) -> ImportedViews:
    """Read and match the images and poses (module docstring). ``model`` turns joint poses
    into flange poses (required for them). One-line ConfigError for every mismatch."""
    paths = find_images(images)
    pf = read_poses(poses, pose_format, joints_expected=model is not None)
    if pf.kind == "joints" and model is None:
        raise ConfigError(f"{pf.path} holds joint angles: name the robot model with --robot")
    if pf.kind != "tcp" and T_flange_tcp is not None:
        raise ConfigError("--tcp applies to TCP poses only")
    matched = _match(paths, pf)
    imgs = [_load(p) for p, _ in matched]
    sizes = {im.shape[1::-1] for im in imgs}
    if len(sizes) != 1:
        listed = ", ".join(f"{w}x{h}" for w, h in sorted(sizes))
        raise ConfigError(f"the images have different sizes ({listed}); one camera, one size")
    flanges, joints = [], [] if pf.kind == "joints" else None
    for _, rec in matched:
        if pf.kind == "joints":
            q = _joints(pf, rec, model)
            joints.append(q)
            flanges.append(model.flange_pose(q))
        else:
            flanges.append(flange_pose(rec, T_flange_tcp))
    return ImportedViews([p for p, _ in matched], imgs, flanges, joints, pf)


def _match(paths: list[Path], pf: PoseFile) -> list[tuple[Path, PoseRecord]]:
    if not pf.named:
        if len(paths) != len(pf.records):
            raise ConfigError(f"{len(paths)} images but {len(pf.records)} poses in {pf.path} "
                              "(matched in order: name the images in the pose file to match "
                              "by name)")
        return list(zip(paths, pf.records, strict=True))
    by_name = {p.name: p for p in paths} | {p.stem: p for p in paths}
    out = []
    for rec in pf.records:
        if rec.name is None:
            raise pf.error(rec, "names no image, while other lines do")
        path = by_name.get(Path(rec.name).name) or by_name.get(Path(rec.name).stem)
        if path is None:
            raise pf.error(rec, f"image {rec.name!r} is not among the --images files")
        out.append((path, rec))
    return out


def _joints(pf: PoseFile, rec: PoseRecord, model: ArmModel) -> np.ndarray:
    q = rec.values
    n = len(model.joint_names)
    if q.size != n:
        raise pf.error(rec, f"{q.size} joint angles, the {model.name} has {n}")
    return q.copy()


def _load(path: Path) -> np.ndarray:
    img = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    if img is None:
        raise ConfigError(f"cannot read the image {path} (not an image, or damaged)")
    if img.dtype == np.uint16:
        img = (img >> 8).astype(np.uint8)
    if img.dtype != np.uint8:
        raise ConfigError(f"{path}: {img.dtype} images are not supported (8 or 16 bit)")
    if img.ndim == 3 and img.shape[2] == 4:
        img = cv2.cvtColor(img, cv2.COLOR_BGRA2BGR)
    return img


def record_imported(views: ImportedViews, board: Board, out: Path, *,
                    intrinsics: Intrinsics | None, model: ArmModel | None,
                    images: str) -> Path:
    """Write the matched views as a calibration recording ``out`` (crash-safe writer)."""
    from armstereo.recording import RecordingWriter

    meta = {**calibration_metadata(board, len(views.paths)), POSE_SOURCE_KEY: IMPORT_SOURCE,
            IMPORT_POSE_KIND_KEY: views.poses.kind, IMPORT_POSES_KEY: str(views.poses.path),
            IMPORT_IMAGES_KEY: json.dumps([p.name for p in views.paths]),
            INTRINSICS_KEY: "given" if intrinsics is not None else "estimated",
            "calibration_images_pattern": images,
            "robot": model.name if model is not None else ""}
    names = list(model.joint_names) if views.joints is not None else []
    with RecordingWriter(out, metadata=meta) as writer:
        if intrinsics is not None:
            writer.write_calibration(intrinsics, VIEW_PERIOD_NS // 2)
        for k, (img, F) in enumerate(zip(views.images, views.flanges, strict=True)):
            q = views.joints[k] if views.joints is not None else np.zeros(0)
            writer.write_view(k, Frame(img, (k + 1) * VIEW_PERIOD_NS), q, names, F, np.eye(4),
                              settle_s=0.0)
    return out
