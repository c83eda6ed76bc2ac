"""The realistic profile's scene: a desk as a camera sees it, not a texture made for the matcher.

Laid out like the demo's table scene (same table top, centred at
:data:`drivers.mock.scene.SCENE_CENTER`, objects within 0.2 m of it, so the same start pose sees
it), but with what makes stereo hard on real desks:

- a plain, low-texture table top (laminate: a few grey levels of contrast) with a faint sheen;
- surfaces textured with real photographs (``textures/``: wood grain, brick, gravel, handwritten
  paper; sources and licences in ``textures/README.md``);
- a repetitive pattern (a keypad of identical 19 mm keys) that offers many equally good matches;
- glossy objects (a ceramic mug, a plastic ball) whose highlights move between the views.
"""

from __future__ import annotations

import functools
from pathlib import Path

import cv2
import numpy as np

from armstereo.errors import ConfigError
from armstereo.transforms import make_T
from drivers.mock.primitives import Box, Cylinder, Rectangle, Sphere
from drivers.mock.render import Scene
from drivers.mock.scene import FLOOR_Z, SCENE_CENTER, TABLE_HALF_SIZE, default_table_scene
from drivers.mock.texture import PhotoTexture, Texture

TEXTURES_DIR = Path(__file__).with_name("textures")
KEY_PITCH_M = 0.019  # a keyboard's key pitch
KEY_TILE_PX = 64


@functools.lru_cache(maxsize=8)
def load_texture(name: str) -> np.ndarray:
    """A bundled photograph (BGR uint8) by file name, e.g. ``wood.jpg``."""
    image = cv2.imread(str(TEXTURES_DIR / name), cv2.IMREAD_COLOR)
    if image is None:
        raise ConfigError(f"mock texture {name} is missing from {TEXTURES_DIR}")
    return image


def key_tile() -> np.ndarray:
    """One key of the keypad (BGR uint8, KEY_TILE_PX square): a light key cap with a soft
    shadowed gap, identical for every key."""
    n = KEY_TILE_PX
    c = (np.arange(n) + 0.5) / n
    edge = np.minimum(np.minimum(c, 1 - c)[:, None], np.minimum(c, 1 - c)[None, :])
    cap = np.clip((edge - 0.06) / 0.06, 0.0, 1.0)  # 0 in the gap, 1 on the cap
    grey = 45 + 150 * cap
    return np.repeat(grey[..., None], 3, axis=2).astype(np.uint8)


def desk_scene(seed: int = 0, *, floor: bool = True) -> Scene:
    """The desk (see module doc); ``seed`` varies the procedural textures only."""
    cx, cy = SCENE_CENTER
    rng = np.random.default_rng(seed)
    table = Rectangle(make_T(np.eye(3), (cx, cy, 0.0)), *TABLE_HALF_SIZE,
                      Texture((122, 130, 138), (134, 142, 150), min_wavelength=0.01,
                              max_wavelength=0.06, contrast=1.0, seed=seed * 1000),
                      name="table").glossy(0.12, 12.0)
    wood = PhotoTexture(load_texture("wood.jpg"), 0.0011)
    paper = PhotoTexture(load_texture("text.png"), 0.0009, gain=1.05, offset=20.0)
    brick = PhotoTexture(load_texture("brick.jpg"), 0.0005, tint_bgr=(0.55, 0.62, 1.0))
    gravel = PhotoTexture(load_texture("gravel.jpg"), 0.0004, tint_bgr=(0.92, 0.96, 1.0))
    keys = PhotoTexture(key_tile(), KEY_PITCH_M / KEY_TILE_PX)
    ceramic = Texture((205, 210, 215), (228, 232, 236), seed=seed * 1000 + 1)
    plastic = Texture((30, 30, 150), (70, 80, 220), seed=seed * 1000 + 2)
    shift = rng.uniform(-0.002, 0.002, 2)  # a seed moves things by millimetres, not the layout

    def at(dx: float, dy: float) -> tuple[float, float]:
        return cx + dx + shift[0], cy + dy + shift[1]

    prims = [
        table,
        Box((*at(-0.12, 0.09), 0.0075), (0.20, 0.14, 0.015), wood, name="tray"),
        Box((*at(0.10, 0.10), 0.001), (0.20, 0.14, 0.002), paper, yaw=-0.15, name="notes"),
        Box((*at(0.07, -0.12), 0.03), (0.12, 0.08, 0.06), brick, yaw=0.3, name="brick"),
        Cylinder(at(-0.08, -0.12), 0.04, 0.10, gravel, name="pot"),
        Box((*at(-0.17, -0.06), 0.01), (0.08, 0.12, 0.02), keys, name="keypad"),
        Cylinder(at(0.16, -0.01), 0.035, 0.09, ceramic, name="mug").glossy(0.5, 60.0),
        Sphere((*at(0.02, -0.01), 0.04), 0.04, plastic, name="ball").glossy(0.6, 80.0),
    ]
    if floor:
        prims.append(Rectangle(make_T(np.eye(3), (cx, cy, FLOOR_Z)), 3.0, 3.0,
                               Texture((60, 60, 60), (110, 110, 110), min_wavelength=0.03,
                                       max_wavelength=0.08, seed=seed * 1000 + 99),
                               name="floor"))
    return Scene(prims, support="table")


def scene_for(name: str, seed: int = 0) -> Scene:
    """The mock scene a profile names: ``table`` (the matcher-friendly demo table) or
    ``desk``."""
    if name == "table":
        return default_table_scene(seed)
    if name == "desk":
        return desk_scene(seed)
    raise ConfigError(f"unknown mock scene {name!r}; choose table or desk")
