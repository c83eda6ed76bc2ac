"""Write an analysis to a folder: ``scene.json``, ``scene.mcap``, ``scene_top.png``,
``height_map.npz`` and ``occupancy.npz`` (formats in ``docs/scene-analysis.md``)."""

from __future__ import annotations

import io
import json
from pathlib import Path

import numpy as np

from armstereo.errors import OutputError
from armstereo.evaluation.scene_score import SceneScore, score_scene
from armstereo.evaluation.scene_truth import SceneTruth
from armstereo.io.files import write_bytes_atomic
from armstereo.io.images import write_png
from armstereo.scene.analysis import SceneAnalysis, SceneOptions, analyze_scene
from armstereo.scene.cloud import SceneCloud, check_cloud
from armstereo.scene.foxglove import write_scene_mcap
from armstereo.scene.render import top_down_image

SCENE_FILES = ("scene.json", "scene.mcap", "scene_top.png", "height_map.npz", "occupancy.npz")


def scene_json(analysis: SceneAnalysis) -> str:
    """The ``scene.json`` text (what ``armstereo analyze --json`` prints)."""
    return json.dumps(analysis.as_dict(), indent=2, allow_nan=False) + "\n"


def write_scene_outputs(analysis: SceneAnalysis, cloud: SceneCloud,
                        out_dir: str | Path) -> dict[str, Path]:
    """Write every file of :data:`SCENE_FILES` into ``out_dir`` (made if missing); returns
    the paths by name."""
    out = Path(out_dir)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise OutputError(f"cannot create output folder {out}: {err.strerror}") from None
    paths = {name: out / name for name in SCENE_FILES}
    write_bytes_atomic(paths["scene.json"], scene_json(analysis).encode())
    write_scene_mcap(paths["scene.mcap"], analysis, cloud)
    write_png(paths["scene_top.png"], top_down_image(analysis, cloud))
    hm = analysis.height_map
    write_bytes_atomic(paths["height_map.npz"], _npz(heights_m=hm.heights,
                                                     cell_m=np.float64(hm.cell_m),
                                                     T_base_grid=hm.T_base_grid))
    write_bytes_atomic(paths["occupancy.npz"], analysis.occupancy.npz_bytes())
    return paths


def analyze_points(points_base: np.ndarray, colors_bgr: np.ndarray | None, out_dir: str | Path,
                   *, source: str, truth: SceneTruth | None = None,
                   options: SceneOptions | None = None,
                   metadata: dict[str, str] | None = None
                   ) -> tuple[SceneAnalysis, SceneScore | None]:
    """Analyse a base-frame cloud held in memory (points (N, 3) m, colours (N, 3) uint8 BGR),
    e.g. the demo's reconstruction; write :data:`SCENE_FILES` (and ``scene_score.json`` when
    ``truth`` is given) into ``out_dir``. Returns the analysis and its score (or None)."""
    meta = dict(metadata or {})
    if truth is not None:
        meta.setdefault("scene_truth", truth.to_json())
    cloud = check_cloud(SceneCloud(np.asarray(points_base, dtype=float), colors_bgr, "base",
                                   source, meta))
    analysis = analyze_scene(cloud, options or SceneOptions())
    write_scene_outputs(analysis, cloud, out_dir)
    score = None
    if truth is not None:
        score = score_scene(analysis, truth)
        text = json.dumps(score.as_dict(), indent=2, allow_nan=False) + "\n"
        write_bytes_atomic(Path(out_dir) / "scene_score.json", text.encode())
    return analysis, score


def _npz(**arrays) -> bytes:
    buf = io.BytesIO()
    np.savez_compressed(buf, **arrays)
    return buf.getvalue()
