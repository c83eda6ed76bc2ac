"""Scoring the demo against the mock's truth: depth per pixel, points against the true
surfaces, the scene step, and the comparison a calibration makes (bundled mount vs calibrated).

The depth score is computed on the left view's pixels that have ground truth and are seen by
the right view too (:mod:`armstereo.evaluation.depth`); ``point_error_mm`` is the distance of
the reconstructed points (base frame) to the scene's true surfaces.
"""

from __future__ import annotations

import numpy as np

from armstereo.errors import RecordingError
from armstereo.evaluation.depth import DepthAccuracy, score_depth, visible_mask
from armstereo.evaluation.scene_truth import SceneTruth

POINT_ERROR_SAMPLES = 50_000  # points scored against the scene truth (every k-th point)


def point_error_mm(points_base: np.ndarray, metadata: dict[str, str]) -> dict:
    """Distance (mm) of reconstructed points (N, 3, base frame) to the recorded scene truth's
    surfaces: median, 90th percentile and the share within 1 mm; None values without truth."""
    text = metadata.get("scene_truth")
    if not text or len(points_base) == 0:
        return {"median": None, "p90": None, "within_1mm": None}
    step = max(1, len(points_base) // POINT_ERROR_SAMPLES)  # a fixed stride: reproducible
    dist = SceneTruth.from_json(text).distance(points_base[::step]) * 1000.0
    return {"median": float(np.median(dist)), "p90": float(np.percentile(dist, 90)),
            "within_1mm": float(np.mean(dist <= 1.0))}


def score_reconstruction(depth, pair, *, swapped: bool = False) -> DepthAccuracy:
    """Score ``depth`` (m, the original view that became the rectified left image) against
    that view's recorded ground truth, on pixels the other view sees too."""
    left, right = (pair.right, pair.left) if swapped else (pair.left, pair.right)
    if left.depth is None or right.depth is None:
        raise RecordingError(f"pair {pair.index} has no ground-truth depth (not a mock capture)")
    mask = visible_mask(left.depth, left.intrinsics, left.T_base_camera, right.depth,
                        right.intrinsics, right.T_base_camera)
    return score_depth(depth, left.depth, mask)


def scene_summary(score: dict) -> dict:
    """The scene score's headline numbers: objects found, phantoms, the table's fit."""
    return {"objects_found": len(score["matched"]), "true_objects": score["true_objects"],
            "phantoms": len(score["phantoms"]), "missed": list(score["missed"]),
            "plane_tilt_deg": score["plane_tilt_deg"],
            "plane_height_error_m": score["plane_height_error_m"]}


def compare_mount(recon, pair, metadata: dict[str, str], truth: SceneTruth | None) -> dict:
    """How one reconstruction of the demo's pair scores: depth, points and (with ``truth``)
    the scene step, without writing anything (the 'before' side of a calibration)."""
    from armstereo.evaluation.scene_score import score_scene
    from armstereo.scene import SceneCloud, SceneError, SceneOptions, analyze_scene, check_cloud

    acc = score_reconstruction(recon.depth_original, pair, swapped=recon.swapped)
    out = {"accuracy": acc.as_dict(), "point_error_mm": point_error_mm(recon.points_base,
                                                                       metadata),
           "points": int(len(recon.points_base)), "photometric": recon.photometric}
    if truth is not None and len(recon.points_base):
        try:
            cloud = check_cloud(SceneCloud(np.asarray(recon.points_base, dtype=float),
                                           recon.colors_bgr, "base", "armstereo demo", {}))
            out["scene"] = scene_summary(score_scene(analyze_scene(cloud, SceneOptions()),
                                                     truth).as_dict())
        except SceneError as err:  # a cloud this wrong has no level table: say so
            out["scene"] = {"error": str(err)}
    return out
