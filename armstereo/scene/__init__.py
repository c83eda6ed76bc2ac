"""Scene analysis: the support plane, the objects on it and a height map, from a base-frame
point cloud (a reconstructed pair or a fused scan). See ``docs/scene-analysis.md``."""

from armstereo.scene.analysis import SceneAnalysis, SceneObject, SceneOptions, analyze_scene
from armstereo.scene.cloud import SceneCloud, check_cloud, load_cloud
from armstereo.scene.errors import SceneError

__all__ = ["SceneAnalysis", "SceneCloud", "SceneError", "SceneObject", "SceneOptions",
           "analyze_scene", "check_cloud", "load_cloud"]
