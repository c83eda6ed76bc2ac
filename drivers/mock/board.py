"""A printed calibration board in the mock world, for ``armstereo calibrate`` on the mock.

The board (an :class:`armstereo.calibration.board.Board`: chessboard or ChArUco) is a
rectangle the size of its printed sheet (squares plus white margin) lying flat on the table,
its centre below the camera of the ``table`` start pose, turned a little about the vertical
(seeded), so a calibration can start from the mock arm's start pose. The table is cleared for
it (the profile's table top and the floor, no objects). Its texture is the board's own
reflectance (``Board.reflectance``), ink and paper grey levels, sampled exactly; the renderer
re-samples pixels on the squares' edges with EDGE_SUPERSAMPLE x EDGE_SUPERSAMPLE rays, so a
corner detector sees anti-aliased edges whose position is not snapped to the pixel grid.

Board frame (armstereo.calibration.board): origin at the outer corner of the top-left square,
x along the columns, y along the rows, z into the board, i.e. pointing down into the table.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from armstereo.transforms import make_T, rot_z
from drivers.mock.primitives import BowedRectangle, Primitive, Rectangle
from drivers.mock.profile import TAG_BOARD, BoardErrors, rng_for
from drivers.mock.render import Scene
from drivers.mock.scene import SCENE_CENTER
from drivers.mock.texture import SurfaceTexture

BOARD_THICKNESS_M = 0.003  # the board's face sits this far above the table top (a stiff board)
INK_GREY = 25.0  # printed black, grey level under full light
PAPER_GREY = 235.0  # paper white
# 4 x 4 rays per edge pixel: detected corners 0.034 px RMS from the projected truth on the
# views of a calibration (6 x 6: 0.031 px at twice the cost; one ray per pixel: 0.11-0.16 px,
# the edges snapped to the pixel grid).
EDGE_SUPERSAMPLE = 4
MAX_YAW_RAD = math.radians(8.0)  # seeded turn of the board about the vertical
MAX_SHIFT_M = 0.01  # seeded shift of its centre from the scene centre
BOARD_YAW_RAD = math.radians(12.0)  # mean turn: edges never line up with the pixel grid


class BoardTexture(SurfaceTexture):
    """Grey BGR of a printed board at a rectangle's surface coordinates: (s, t) are metres
    from the rectangle's centre along its local x and y, which are the board's x and y. The
    print is ``scale`` times the size its spec says (about the sheet's centre)."""

    def __init__(self, board, sheet_center_xy: tuple[float, float], scale: float = 1.0):
        self.board = board
        self._center = np.asarray(sheet_center_xy, dtype=float)
        self.scale = float(scale)

    def sample(self, s: np.ndarray, t: np.ndarray) -> np.ndarray:
        st = np.stack([np.ravel(s), np.ravel(t)], axis=1).astype(float)
        xy = (st if self.scale == 1.0 else st / self.scale) + self._center
        r = self.board.reflectance(xy)
        r = np.where(np.isnan(r), 1.0, r)  # a sample on the sheet's very rim: paper
        grey = (INK_GREY + (PAPER_GREY - INK_GREY) * r).astype(np.float32)
        return np.repeat(grey[None, :], 3, axis=0)


def sheet_extent(board) -> tuple[float, float, float, float]:
    """Board-frame bounds (x0, y0, x1, y1) of the printed sheet (m): squares plus margin."""
    img, px_per_m, margin = board.texture
    return -margin, -margin, img.shape[1] / px_per_m - margin, img.shape[0] / px_per_m - margin


def board_pose(board, seed: int = 0) -> np.ndarray:
    """T_base_board of the board on the table (base frame, m): its squares' centre within
    MAX_SHIFT_M of the scene centre, printed face up (board z points down), turned
    BOARD_YAW_RAD +- MAX_YAW_RAD about the vertical (seeded)."""
    rng = np.random.default_rng([int(seed), 21])
    yaw = BOARD_YAW_RAD + rng.uniform(-MAX_YAW_RAD, MAX_YAW_RAD)
    shift = rng.uniform(-MAX_SHIFT_M, MAX_SHIFT_M, 2)
    # Face up: board x along base x, board y along -base y, board z along -base z; then yaw.
    R = rot_z(yaw) @ np.diag([1.0, -1.0, -1.0])
    center = np.array([SCENE_CENTER[0] + shift[0], SCENE_CENTER[1] + shift[1],
                       BOARD_THICKNESS_M])
    return make_T(R, center - R @ board.center)


@dataclass(frozen=True)
class PrintedBoard:
    """How this cell's board really is (drawn from a profile's BoardErrors): ``scale`` (the
    print's size over its spec's), ``curv_x``/``curv_y`` (1/m: the sheet's bow, board frame,
    z down: z = curv_x x^2 + curv_y y^2 - sag about the sheet's centre, so its corners touch
    the plane and its centre is lifted ``sag_m`` off it) and the laminate's glare
    (Blinn-Phong strength and exponent)."""

    scale: float = 1.0
    curv_x: float = 0.0
    curv_y: float = 0.0
    glare: float = 0.0
    glare_shininess: float = 60.0

    @property
    def flat(self) -> bool:
        return self.curv_x == 0.0 and self.curv_y == 0.0

    def sag_m(self, half_x: float, half_y: float) -> float:
        return self.curv_x * half_x ** 2 + self.curv_y * half_y ** 2

    def as_dict(self, board) -> dict:
        x0, y0, x1, y1 = sheet_extent(board)
        hx, hy = self.scale * (x1 - x0) / 2, self.scale * (y1 - y0) / 2
        return {"scale": self.scale, "sag_m": self.sag_m(hx, hy), "glare": self.glare}


def printed_board(errors: BoardErrors | None, board, seed: int = 0) -> PrintedBoard:
    """The cell's print of ``board`` (seeded): scale error, bow (split between the sheet's
    two axes), glare."""
    unit = rng_for(seed, TAG_BOARD).standard_normal(3)  # always drawn
    if errors is None:
        return PrintedBoard()
    x0, y0, x1, y1 = sheet_extent(board)
    hx, hy = (x1 - x0) / 2, (y1 - y0) / 2
    sag = abs(errors.bow_m * unit[1])  # the centre lifted off the table by this much
    share = float(np.clip(0.5 + 0.3 * unit[2], 0.0, 1.0))
    return PrintedBoard(scale=1.0 + errors.scale_rel * unit[0],
                        curv_x=sag * share / hx ** 2, curv_y=sag * (1.0 - share) / hy ** 2,
                        glare=errors.glare, glare_shininess=errors.glare_shininess)


def board_primitive(board, T_base_board: np.ndarray,
                    printed: PrintedBoard | None = None) -> Rectangle:
    """The printed sheet at ``T_base_board`` (textured, sharp edges): a rectangle, or with
    ``printed`` the cell's print of it (scaled, bowed, glossy)."""
    printed = printed or PrintedBoard()
    x0, y0, x1, y1 = sheet_extent(board)
    cx, cy = (x0 + x1) / 2, (y0 + y1) / 2
    T = T_base_board @ make_T(np.eye(3), (cx, cy, 0.0))
    hx, hy = printed.scale * (x1 - x0) / 2, printed.scale * (y1 - y0) / 2
    texture = BoardTexture(board, (cx, cy), printed.scale)
    if printed.flat:
        rect = Rectangle(T, hx, hy, texture, name="calibration_board")
    else:
        rect = BowedRectangle(T, hx, hy, texture, curv_x=printed.curv_x,
                              curv_y=printed.curv_y, name="calibration_board")
    if printed.glare > 0:
        rect.glossy(printed.glare, printed.glare_shininess)
    rect.edge_supersample = EDGE_SUPERSAMPLE
    return rect


def calibration_scene(board, base: Scene, seed: int = 0,
                      errors: BoardErrors | None = None) -> Scene:
    """``base``'s table top and floor (its objects cleared away) with ``board`` lying on the
    table (:func:`board_pose`), printed as ``errors`` (a profile's BoardErrors) say."""
    keep: list[Primitive] = [p for p in base.primitives if p.name in ("table", "floor")]
    rect = board_primitive(board, board_pose(board, seed), printed_board(errors, board, seed))
    return Scene([rect, *keep], light_dir=base.light_dir, ambient=base.ambient,
                 background_bgr=base.background, support=base.support)
