"""Calibration boards: parse a spec, know the corners' 3D positions, detect them, render them.

Specs (``--board``), sizes in metres, COLS and ROWS count *squares* for both kinds (what you
count on the print; a chessboard of COLSxROWS squares has (COLS-1)x(ROWS-1) inner corners)::

    chessboard:COLSxROWS:SQUARE_M             e.g. chessboard:10x7:0.025
    charuco:COLSxROWS:SQUARE_M:MARKER_M[:DICT] e.g. charuco:7x5:0.04:0.03:DICT_5X5_100

Board frame: origin at the outer corner of the top-left square (which is black), x along the
COLS squares, y along the ROWS squares, z = x cross y, i.e. *into* the board, away from a
camera that looks at the printed face (OpenCV's convention). Inner corner ``id`` sits at
``((id % (COLS-1) + 1) * SQUARE, (id // (COLS-1) + 1) * SQUARE, 0)``; OpenCV's ChArUco boards
number their corners the same way.

A chessboard must have an odd number of squares on one side and an even number on the other:
only then do its two black corner squares sit on one side, so that a view of it has one
reading (a board symmetric under a half turn gives corner orders that differ by 180 degrees
between views, and the hand-eye solution would be garbage).
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from functools import cached_property

import cv2
import numpy as np

from armstereo.camera_model import Intrinsics
from armstereo.errors import ConfigError

CHESSBOARD = "chessboard"
CHARUCO = "charuco"
DEFAULT_DICTIONARY = "DICT_5X5_100"
MIN_SQUARES = 3  # per side
MAX_SQUARES = 60
MIN_SQUARE_M = 0.002  # smaller is surely millimetres typed as metres the other way round
MAX_SQUARE_M = 0.5  # larger is surely millimetres typed where metres are expected
# ChArUco views with fewer corners than this are not used (a pose needs a spread of points).
MIN_CHARUCO_CORNERS = 6
# cornerSubPix half-window as a fraction of the corner spacing: large enough to see the
# corner's four edges, small enough never to reach the neighbouring corner.
SUBPIX_WINDOW_FRACTION = 0.35
SUBPIX_WINDOW_MIN, SUBPIX_WINDOW_MAX = 2, 10
_SUBPIX_CRITERIA = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 50, 1e-4)
TEXTURE_PX_PER_SQUARE = 96  # resolution of the flat board image used for rendering views
CHESSBOARD_MARGIN_SQUARES = 1.0  # white border of a rendered chessboard (detectors need one)
CHARUCO_MARGIN_SQUARES = 0.5

_SPEC_RE = re.compile(r"^\s*(\d+)\s*[xX]\s*(\d+)\s*$")


@dataclass(frozen=True)
class Board:
    """A planar calibration board (see the module docstring for the spec and frame)."""

    kind: str
    cols: int  # squares along the board's x axis
    rows: int  # squares along y
    square_m: float
    marker_m: float = 0.0  # ChArUco only
    dictionary: str = ""  # ChArUco only, an OpenCV DICT_* name

    @property
    def spec(self) -> str:
        """The board as a ``--board`` spec (round-trips through :func:`parse_board`)."""
        base = f"{self.kind}:{self.cols}x{self.rows}:{self.square_m:g}"
        if self.kind == CHARUCO:
            return f"{base}:{self.marker_m:g}:{self.dictionary}"
        return base

    @property
    def inner_size(self) -> tuple[int, int]:
        """Inner corners per row and per column: (cols - 1, rows - 1)."""
        return self.cols - 1, self.rows - 1

    @property
    def corner_count(self) -> int:
        return (self.cols - 1) * (self.rows - 1)

    @property
    def size_m(self) -> tuple[float, float]:
        """Width and height of the squared area (m), without any printed margin."""
        return self.cols * self.square_m, self.rows * self.square_m

    @cached_property
    def object_points(self) -> np.ndarray:
        """(N, 3) float64 board-frame coordinates (m) of every inner corner, row-major by id."""
        w, h = self.inner_size
        c, r = np.meshgrid(np.arange(w), np.arange(h))
        pts = np.stack([(c.ravel() + 1) * self.square_m, (r.ravel() + 1) * self.square_m,
                        np.zeros(c.size)], axis=1)
        pts.setflags(write=False)
        return pts

    @property
    def center(self) -> np.ndarray:
        """Centre of the squared area in the board frame (m), shape (3,)."""
        w, h = self.size_m
        return np.array([w / 2, h / 2, 0.0])

    def describe(self) -> str:
        w, h = self.inner_size
        text = (f"{self.kind} {self.cols}x{self.rows} squares of {self.square_m * 1000:g} mm "
                f"({w}x{h} = {self.corner_count} inner corners, "
                f"{self.size_m[0] * 1000:g} x {self.size_m[1] * 1000:g} mm)")
        if self.kind == CHARUCO:
            text += f", markers {self.marker_m * 1000:g} mm {self.dictionary}"
        return text

    @cached_property
    def _cv_board(self):
        """The OpenCV ChArUco board (ChArUco only)."""
        dictionary = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, self.dictionary))
        return cv2.aruco.CharucoBoard((self.cols, self.rows), self.square_m, self.marker_m,
                                      dictionary)

    # ------------------------------------------------------------------------------ rendering
    @cached_property
    def texture(self) -> tuple[np.ndarray, float, float]:
        """Flat image of the printed board: (uint8 grey image, px per metre, margin in m).

        Pixel (row i, col j) covers board-frame x in ``[j, j+1) / px_per_m - margin`` (same
        for y with i). The board is white outside its squares up to the margin.
        """
        n = TEXTURE_PX_PER_SQUARE
        if self.kind == CHARUCO:
            margin_sq = CHARUCO_MARGIN_SQUARES
            img = self._cv_board.generateImage((self.cols * n, self.rows * n), marginSize=0,
                                               borderBits=1)
        else:
            margin_sq = CHESSBOARD_MARGIN_SQUARES
            a, b = np.meshgrid(np.arange(self.cols * n) // n, np.arange(self.rows * n) // n)
            img = np.where((a + b) % 2 == 0, 0, 255).astype(np.uint8)
        pad = int(round(margin_sq * n))
        img = cv2.copyMakeBorder(img, pad, pad, pad, pad, cv2.BORDER_CONSTANT, value=255)
        return img, n / self.square_m, pad / n * self.square_m

    def reflectance(self, xy_board: np.ndarray) -> np.ndarray:
        """Grey level 0..1 of the printed board at board-frame points (N, 2) metres; NaN
        outside the printed sheet (squares plus white margin). For a mock scene's texture."""
        img, px_per_m, margin = self.texture
        p = (np.asarray(xy_board, dtype=float).reshape(-1, 2) + margin) * px_per_m
        j, i = np.floor(p[:, 0]).astype(int), np.floor(p[:, 1]).astype(int)
        inside = (i >= 0) & (j >= 0) & (i < img.shape[0]) & (j < img.shape[1])
        out = np.full(len(p), np.nan)
        out[inside] = img[i[inside], j[inside]] / 255.0
        return out


# -------------------------------------------------------------------------------- parsing
def parse_board(text: str) -> Board:
    """Parse a ``--board`` spec (module docstring); ConfigError saying what is wrong."""
    parts = [p.strip() for p in str(text).split(":")]
    kind = parts[0].lower()
    if kind not in (CHESSBOARD, CHARUCO):
        raise ConfigError(f"--board must start with '{CHESSBOARD}:' or '{CHARUCO}:', "
                          f"not {text!r}")
    want = "chessboard:COLSxROWS:SQUARE_M" if kind == CHESSBOARD else \
        "charuco:COLSxROWS:SQUARE_M:MARKER_M[:DICT]"
    n_ok = (3,) if kind == CHESSBOARD else (4, 5)
    if len(parts) not in n_ok:
        raise ConfigError(f"--board {text!r} must look like {want}")
    m = _SPEC_RE.match(parts[1])
    if not m:
        raise ConfigError(f"--board {text!r}: '{parts[1]}' must be COLSxROWS (squares), "
                          "e.g. 10x7")
    cols, rows = int(m.group(1)), int(m.group(2))
    if not (MIN_SQUARES <= cols <= MAX_SQUARES and MIN_SQUARES <= rows <= MAX_SQUARES):
        raise ConfigError(f"--board {text!r}: squares per side must be in "
                          f"{MIN_SQUARES}..{MAX_SQUARES}, got {cols}x{rows}")
    square = _length(parts[2], "SQUARE_M", text)
    if kind == CHESSBOARD:
        if (cols + rows) % 2 == 0:
            raise ConfigError(
                f"--board {text!r}: a {cols}x{rows} chessboard looks the same turned by 180 "
                "degrees, so views cannot agree on its corner order; use a board with an odd "
                f"number of squares on one side and an even number on the other (e.g. "
                f"{cols}x{rows + 1})")
        return Board(CHESSBOARD, cols, rows, square)
    marker = _length(parts[3], "MARKER_M", text)
    if not marker < square:
        raise ConfigError(f"--board {text!r}: the marker ({marker:g} m) must be smaller than "
                          f"the square ({square:g} m)")
    dictionary = _dictionary_name(parts[4] if len(parts) == 5 else DEFAULT_DICTIONARY, text)
    board = Board(CHARUCO, cols, rows, square, marker, dictionary)
    needed = cols * rows // 2
    available = board._cv_board.getDictionary().bytesList.shape[0]
    if needed > available:
        raise ConfigError(f"--board {text!r}: a {cols}x{rows} ChArUco board needs {needed} "
                          f"markers but {dictionary} has {available}; use a larger dictionary")
    return board


def _length(text: str, what: str, spec: str) -> float:
    try:
        v = float(text)
    except ValueError:
        v = math.nan
    if not math.isfinite(v) or v <= 0:
        raise ConfigError(f"--board {spec!r}: {what} must be a positive length in metres, "
                          f"not {text!r}")
    if not MIN_SQUARE_M <= v <= MAX_SQUARE_M:
        hint = f" (did you mean {v / 1000:g}?)" if v > MAX_SQUARE_M else ""
        raise ConfigError(f"--board {spec!r}: {what} = {v:g} m is outside "
                          f"[{MIN_SQUARE_M:g}, {MAX_SQUARE_M:g}] m; sizes are in metres{hint}")
    return v


def _dictionary_name(text: str, spec: str) -> str:
    name = text.strip().upper()
    if not name.startswith("DICT_"):
        name = "DICT_" + name
    known = sorted(n for n in dir(cv2.aruco) if n.startswith("DICT_") and n == n.upper())
    if name not in known:
        raise ConfigError(f"--board {spec!r}: unknown ArUco dictionary {text!r}; known: "
                          f"{', '.join(known)}")
    return name


# ------------------------------------------------------------------------------ detection
@dataclass(frozen=True)
class Detection:
    """Board corners found in one image.

    ``ids`` (N,) int corner ids, ``image_points`` (N, 2) float64 pixels (OpenCV convention:
    integer coordinates at pixel centres), ``object_points`` (N, 3) float64 board frame (m).
    """

    ids: np.ndarray
    image_points: np.ndarray
    object_points: np.ndarray

    def __len__(self) -> int:
        return len(self.ids)

    @property
    def spacing_px(self) -> float:
        """Median image distance between neighbouring corners (px): how large the board looks."""
        return _median_spacing(self.image_points, self.object_points)


def detect_board(image: np.ndarray, board: Board) -> Detection | None:
    """Find the board's inner corners in a uint8 grey or BGR image, sub-pixel refined.

    Returns None when the board is not found (or, for ChArUco, fewer than
    MIN_CHARUCO_CORNERS corners are). Chessboard corners come back in the board's own order
    whatever the view (mirror and half-turn readings are resolved from the square colours).
    """
    grey = _grey(image)
    if board.kind == CHARUCO:
        return _detect_charuco(grey, board)
    return _detect_chessboard(grey, board)


def _grey(image: np.ndarray) -> np.ndarray:
    img = np.asarray(image)
    if img.dtype != np.uint8 or img.ndim not in (2, 3):
        raise ConfigError(f"images must be uint8 grey or BGR, got {img.dtype} {img.shape}")
    if img.ndim == 3:
        if img.shape[2] == 1:
            return img[:, :, 0]
        return cv2.cvtColor(img, cv2.COLOR_BGR2GRAY)
    return img


def _detect_chessboard(grey: np.ndarray, board: Board) -> Detection | None:
    size = board.inner_size
    flags = cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE
    found, corners = cv2.findChessboardCorners(grey, size, flags=flags)
    if not found:
        return None
    pts = corners.reshape(-1, 2).astype(np.float64)
    pts = _canonical_order(grey, pts, board)
    pts = _refine_corners(grey, pts, board)
    ids = np.arange(board.corner_count)
    return Detection(ids, pts, board.object_points.copy())


def _refine_corners(grey: np.ndarray, pts: np.ndarray, board: Board) -> np.ndarray:
    spacing = _median_spacing(pts, board.object_points)
    half = int(np.clip(round(SUBPIX_WINDOW_FRACTION * spacing), SUBPIX_WINDOW_MIN,
                       SUBPIX_WINDOW_MAX))
    refined = cv2.cornerSubPix(grey, pts.astype(np.float32).reshape(-1, 1, 2), (half, half),
                               (-1, -1), _SUBPIX_CRITERIA)
    return refined.reshape(-1, 2).astype(np.float64)


def _canonical_order(grey: np.ndarray, pts: np.ndarray, board: Board) -> np.ndarray:
    """Reorder OpenCV's corners into the board's ids: undo a mirrored reading (the board's
    front face must map to the image without reflection), then a half turn (square (1, 1),
    between the first four inner corners, is black)."""
    w, h = board.inner_size
    grid = pts.reshape(h, w, 2)
    obj2 = board.object_points[:, :2]
    H, _ = cv2.findHomography(obj2, grid.reshape(-1, 2))
    if H is not None and _homography_orientation(H, board.center[:2]) < 0:
        grid = grid[:, ::-1]
        H, _ = cv2.findHomography(obj2, grid.reshape(-1, 2))
    if H is not None and _black_looks_white(grey, H, board):
        grid = grid[::-1, ::-1]
    return np.ascontiguousarray(grid.reshape(-1, 2))


def _homography_orientation(H: np.ndarray, p: np.ndarray) -> float:
    """Sign of the Jacobian determinant of the homography at board point p (2,)."""
    x = np.array([p[0], p[1], 1.0])
    y = H @ x
    J = (H[:2, :2] * y[2] - np.outer(y[:2], H[2, :2])) / y[2] ** 2
    return float(np.sign(np.linalg.det(J)))


def _black_looks_white(grey: np.ndarray, H: np.ndarray, board: Board) -> bool:
    """True if the interior squares that should be black are brighter than the white ones."""
    s = board.square_m
    a, b = np.meshgrid(np.arange(1, board.cols - 1), np.arange(1, board.rows - 1))
    centres = np.stack([(a.ravel() + 0.5) * s, (b.ravel() + 0.5) * s], axis=1)
    px = cv2.perspectiveTransform(centres.reshape(-1, 1, 2), H).reshape(-1, 2)
    cols = np.clip(np.rint(px[:, 0]).astype(int), 0, grey.shape[1] - 1)
    rows = np.clip(np.rint(px[:, 1]).astype(int), 0, grey.shape[0] - 1)
    values = grey[rows, cols].astype(float)
    black = ((a + b).ravel() % 2) == 0
    return bool(values[black].mean() > values[~black].mean())


def _detect_charuco(grey: np.ndarray, board: Board) -> Detection | None:
    detector = cv2.aruco.CharucoDetector(board._cv_board)
    corners, ids, _, _ = detector.detectBoard(grey)
    if corners is None or ids is None or len(ids) < MIN_CHARUCO_CORNERS:
        return None
    ids = ids.reshape(-1).astype(int)
    order = np.argsort(ids)
    ids = ids[order]
    pts = corners.reshape(-1, 2).astype(np.float64)[order]
    return Detection(ids, pts, board.object_points[ids].copy())


def _median_spacing(image_points: np.ndarray, object_points: np.ndarray) -> float:
    """Median pixel distance between corners one square apart (nearest neighbours)."""
    img = np.asarray(image_points, dtype=float)
    obj = np.asarray(object_points, dtype=float)[:, :2]
    if len(img) < 2:
        return 0.0
    d_obj = np.linalg.norm(obj[:, None] - obj[None], axis=2)
    step = np.min(d_obj[d_obj > 0])
    i, j = np.nonzero(np.isclose(d_obj, step) & np.triu(np.ones_like(d_obj, bool), 1))
    if len(i) == 0:
        return 0.0
    return float(np.median(np.linalg.norm(img[i] - img[j], axis=1)))


# ------------------------------------------------------------------------------ rendering
def render_board_view(board: Board, intrinsics: Intrinsics, T_camera_board: np.ndarray, *,
                      background: int = 110, supersample: int = 3,
                      noise_sigma: float = 0.0, seed: int = 0) -> np.ndarray:
    """Grey uint8 image (H, W) of the printed board seen by a camera (lens distortion
    included), for tests and simulations.

    ``T_camera_board`` places the board frame in camera_optical (m). Each pixel averages
    ``supersample`` x ``supersample`` rays (anti-aliased edges, like a real sensor); pixels
    that miss the sheet show ``background``. ``noise_sigma`` adds seeded Gaussian noise (grey
    levels).
    """
    T = np.asarray(T_camera_board, dtype=float)
    if T.shape != (4, 4):
        raise ConfigError(f"T_camera_board must be 4x4, got {T.shape}")
    s = int(supersample)
    xn, yn = _ray_grid(intrinsics, s)
    R, t = T[:3, :3], T[:3, 3]
    n = R[:, 2]  # board normal in the camera frame
    denom = n[0] * xn + n[1] * yn + n[2]
    with np.errstate(divide="ignore", invalid="ignore"):
        lam = float(n @ t) / denom  # ray parameter = z-depth of the hit
    hit = np.isfinite(lam) & (lam > 0)
    # board coordinates of the hit: R^T (lam * ray - t)
    px, py, pz = lam * xn - t[0], lam * yn - t[1], lam - t[2]
    bx = R[0, 0] * px + R[1, 0] * py + R[2, 0] * pz
    by = R[0, 1] * px + R[1, 1] * py + R[2, 1] * pz
    img, px_per_m, margin = board.texture
    map_x = np.where(hit, (bx + margin) * px_per_m - 0.5, -10.0).astype(np.float32)
    map_y = np.where(hit, (by + margin) * px_per_m - 0.5, -10.0).astype(np.float32)
    fine = cv2.remap(img, map_x, map_y, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT,
                     borderValue=int(background))
    out = cv2.resize(fine.astype(np.float32), intrinsics.size, interpolation=cv2.INTER_AREA)
    if noise_sigma > 0:
        out = out + np.random.default_rng(seed).normal(0.0, noise_sigma, out.shape)
    return np.clip(np.rint(out), 0, 255).astype(np.uint8)


_RAY_CACHE: dict[tuple, tuple[np.ndarray, np.ndarray]] = {}


def _ray_grid(intr: Intrinsics, s: int) -> tuple[np.ndarray, np.ndarray]:
    """Normalised rays (x/z, y/z) through an s x s sub-pixel grid, (H*s, W*s) float64 each."""
    key = (intr.width, intr.height, intr.K.tobytes(), intr.dist.tobytes(), s)
    if key in _RAY_CACHE:
        return _RAY_CACHE[key]
    u = (np.arange(intr.width * s) + 0.5) / s - 0.5
    v = (np.arange(intr.height * s) + 0.5) / s - 0.5
    uu, vv = np.meshgrid(u, v)
    if intr.has_distortion:
        pts = np.stack([uu.ravel(), vv.ravel()], axis=1).reshape(-1, 1, 2)
        crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 50, 1e-10)
        und = cv2.undistortPointsIter(pts, intr.K, intr.dist, None, None, crit).reshape(-1, 2)
        xn, yn = und[:, 0].reshape(uu.shape), und[:, 1].reshape(uu.shape)
    else:
        yn = (vv - intr.cy) / intr.fy
        xn = (uu - intr.cx - intr.K[0, 1] * yn) / intr.fx
    if len(_RAY_CACHE) > 4:
        _RAY_CACHE.pop(next(iter(_RAY_CACHE)))
    _RAY_CACHE[key] = (xn, yn)
    return xn, yn
