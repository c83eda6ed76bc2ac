"""Write an analysis to a folder: ``scene.json``, ``scene.mcap``, ``scene_top.png``,
``height_map.npz`` and ``occupancy.npz`` (formats in ``docs/scene-analysis.md``)."""

from __future__ import annotations

import io
import json
from pathlib import Path

import numpy as np

from armstereo.errors import ConfigError
from armstereo.ply import write_bytes_atomic
from armstereo.scene.analysis import SceneAnalysis
from armstereo.scene.cloud import SceneCloud
from armstereo.scene.foxglove import write_scene_mcap
from armstereo.scene.render import top_down_image
from armstereo.visualize import write_png

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
        raise ConfigError(f"cannot create output folder {out}: {err.strerror}") from None
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


def _npz(**arrays) -> bytes:
    buf = io.BytesIO()
    np.savez_compressed(buf, **arrays)
    return buf.getvalue()
