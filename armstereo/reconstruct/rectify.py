"""Fusiello rectification of a stereo pair whose two camera poses are known.

Fusiello, Trucco and Verri (2000) turn two projection matrices into two new ones that share
orientation and intrinsics and differ only by a translation along the new x axis (the
baseline), so epipolar lines become image rows. Conventions used here:

* Projection matrices map ``base``-frame points (metres) to pixels; pixel centres sit at
  integer coordinates (OpenCV's convention, so a 640x480 image's centre is (319.5, 239.5)).
* ``v1 = c2 - c1`` (the RectifKit fix of the paper's printed sign): camera 1 is the left one,
  disparities ``d = x_left - x_right`` are positive and ``Z = fx * b / (d - (cx1 - cx2))``.
* The new intrinsics have zero skew and square pixels (``fx == fy``) unless asked otherwise, so
  the standard Q matrix holds (the paper's averaged A has fx != fy: docs/rectification.md §6).
* Homographies ``H`` map original pixels to rectified pixels and include the centering of the
  warped images (RectifKit) and the shared canvas offset; they describe a distortion-free
  pinhole. :func:`rectify_pair` removes lens distortion in the same ``cv2.remap``.
* Any baseline direction works. :func:`rectify_pair` picks as "left" the view from which the
  other one lies at an image-plane angle in (-90, 90] deg, so the rectified images are rotated
  by at most 90 deg (a vertical baseline gives images rotated by 90 deg; rows are still the
  epipolar lines and the matcher runs along rows).

:class:`RectificationPlan` checks a pair's poses and solves its rectification once; its
:meth:`~RectificationPlan.geometry` and :meth:`~RectificationPlan.rectify` (what
:func:`rectified_geometry` and :func:`rectify_pair` run) reuse it. The results' types are in
:mod:`.rectified`.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, replace

import cv2
import numpy as np

from armstereo.camera_model import Intrinsics
from armstereo.errors import StereoError
from armstereo.reconstruct.rectified import Rectification, RectifiedPair, StereoGeometry
from armstereo.transforms import as_rigid, invert

log = logging.getLogger(__name__)

MIN_BASELINE_ANGLE_DEG = 5.0  # below this angle to the optical axis the problem is degenerate
MAX_CANVAS_SCALE = 1.5  # rectified canvas sides are capped at this multiple of the input's
MAP_TOLERANCE = 1e-3  # px: float32 maps land a hair outside the image on its border


# ----------------------------------------------------------------------------------------------
# Factorisation
# ----------------------------------------------------------------------------------------------
def rq(M: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """RQ decomposition ``M = U @ Q`` of a 3x3 matrix, U upper triangular with positive diagonal.

    Q is orthogonal (its determinant carries the sign of det M). Computed as a QR decomposition of
    the row-flipped, transposed matrix, so no scipy is needed.
    """
    M = np.asarray(M, dtype=float)
    flip = np.eye(3)[::-1]
    q, r = np.linalg.qr((flip @ M).T)
    U = flip @ r.T @ flip
    Q = flip @ q.T
    signs = np.sign(np.diag(U))
    signs[signs == 0] = 1.0
    return U * signs, signs[:, None] * Q  # U @ diag(s) @ diag(s) @ Q == U @ Q


def factor_projection(P: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Split a 3x4 PPM into ``(A, R, c)`` with ``P ~ A [R | -R c]``.

    A is upper triangular with a positive diagonal and ``A[2, 2] == 1``, R a proper rotation
    (det +1) and c the optical centre ``-Q^-1 q``. Any non-zero scale of P, including a negative
    one, gives the same result. Raises StereoError when P's left 3x3 block is singular.
    """
    P = _as_ppm(P)
    Q, q = P[:, :3], P[:, 3]
    det = float(np.linalg.det(Q))
    if not np.isfinite(det) or abs(det) <= 1e-12 * np.linalg.norm(Q) ** 3:
        raise StereoError(f"projection matrix has a singular left 3x3 block (det {det:.3g})")
    U, Rq = rq(Q)
    A = U / U[2, 2]
    R = Rq * np.sign(np.linalg.det(Rq))  # Q = (s U[2,2]) A (s Rq): absorb the sign into the scale
    return A, R, -np.linalg.solve(Q, q)


def _as_ppm(P: np.ndarray) -> np.ndarray:
    P = np.asarray(P, dtype=float)
    if P.shape != (3, 4) or not np.all(np.isfinite(P)):
        raise StereoError(f"a projection matrix must be a finite 3x4 array, got shape {P.shape}")
    return P


# ----------------------------------------------------------------------------------------------
# The rectified rig (internal: intrinsics per camera after centering/offsets)
# ----------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class _Rig:
    """Old factors of both cameras, the shared new rotation and each camera's new intrinsics."""

    A1: np.ndarray
    R1: np.ndarray
    c1: np.ndarray
    A2: np.ndarray
    R2: np.ndarray
    c2: np.ndarray
    Rn: np.ndarray
    An1: np.ndarray
    An2: np.ndarray
    angle_deg: float  # angle between the baseline and camera 1's optical axis

    def homography(self, i: int) -> np.ndarray:
        """``An_i Rn R_i^T A_i^-1``: positive-scale form, so w > 0 means 'in front'."""
        A, R, An = (self.A1, self.R1, self.An1) if i == 1 else (self.A2, self.R2, self.An2)
        return An @ self.Rn @ R.T @ np.linalg.inv(A)

    def ppm(self, i: int) -> np.ndarray:
        An, c = (self.An1, self.c1) if i == 1 else (self.An2, self.c2)
        return An @ np.hstack([self.Rn, (-self.Rn @ c)[:, None]])

    def rectification(self) -> Rectification:
        return Rectification(self.homography(1), self.homography(2), self.ppm(1), self.ppm(2))

    def shifted(self, d1: tuple[float, float], d2: tuple[float, float]) -> _Rig:
        """Move each camera's principal point by (du, dv) pixels (a pure image translation)."""
        return replace(self, An1=_shift_pp(self.An1, d1), An2=_shift_pp(self.An2, d2))


def _shift_pp(A: np.ndarray, d: tuple[float, float]) -> np.ndarray:
    A = A.copy()
    A[0, 2] += d[0]
    A[1, 2] += d[1]
    return A


def _solve(P1: np.ndarray, P2: np.ndarray, *, square_pixels: bool) -> _Rig:
    """The paper's algorithm without any image shift (docs/rectification.md §3-5)."""
    P1, P2 = _as_ppm(P1), _as_ppm(P2)
    A1, R1, c1 = factor_projection(P1)
    A2, R2, c2 = factor_projection(P2)
    Q1 = P1[:, :3]
    # The old viewing direction from P alone (Hartley-Zisserman's principal axis), immune to the
    # factorisation's sign choices; equals R1[2].
    k = np.sign(np.linalg.det(Q1)) * Q1[2] / np.linalg.norm(Q1[2])
    v1 = c2 - c1
    b = float(np.linalg.norm(v1))
    if b <= 1e-12 * max(1.0, float(np.linalg.norm(c1)), float(np.linalg.norm(c2))):
        raise StereoError(f"baseline is {b:.3g}: both views were taken from the same place")
    r1 = v1 / b
    kx = np.cross(k, r1)
    sin_angle = float(np.linalg.norm(kx))
    angle = math.degrees(math.asin(min(1.0, sin_angle)))
    if angle < MIN_BASELINE_ANGLE_DEG:
        raise StereoError(f"baseline is along the optical axis (angle {angle:.1f} deg): "
                          "rectification needs a sideways motion "
                          f"(at least {MIN_BASELINE_ANGLE_DEG:g} deg)")
    r2 = kx / sin_angle
    r3 = np.cross(r1, r2)
    Rn = np.vstack([r1, r2, r3 / np.linalg.norm(r3)])
    An = (A1 + A2) / 2.0
    An[0, 1] = 0.0
    if square_pixels:
        An[0, 0] = An[1, 1] = (An[0, 0] + An[1, 1]) / 2.0
    return _Rig(A1, R1, c1, A2, R2, c2, Rn, An, An.copy(), angle)


def _dehom(H: np.ndarray, pts: np.ndarray) -> np.ndarray:
    """Apply a homography to Nx2 points; raises StereoError if any lands behind the camera."""
    h = np.c_[pts, np.ones(len(pts))] @ H.T
    if np.any(h[:, 2] <= 0):
        raise StereoError("part of a view maps behind the rectified camera: the baseline is too "
                          "close to the optical axis for this field of view; move sideways")
    return h[:, :2] / h[:, 2:]


def _centre_of(size: tuple[int, int]) -> np.ndarray:
    return np.array([(size[0] - 1) / 2.0, (size[1] - 1) / 2.0])


def _corners(size: tuple[int, int]) -> np.ndarray:
    w, h = size[0] - 1.0, size[1] - 1.0
    return np.array([[0.0, 0.0], [w, 0.0], [w, h], [0.0, h]])


def _centre(rig: _Rig, size1: tuple[int, int], size2: tuple[int, int]) -> _Rig:
    """RectifKit centering: each image's centre maps to itself, with one shared vertical shift.

    The shared shift is the mean of the two vertical shifts (RectifKit copies the right one);
    rows stay aligned because both cameras move by the same amount.
    """
    d1 = _centre_of(size1) - _dehom(rig.homography(1), _centre_of(size1)[None])[0]
    d2 = _centre_of(size2) - _dehom(rig.homography(2), _centre_of(size2)[None])[0]
    dy = (d1[1] + d2[1]) / 2.0
    return rig.shifted((d1[0], dy), (d2[0], dy))


def warped_bounds(H: np.ndarray, size: tuple[int, int]) -> tuple[float, float, float, float]:
    """(xmin, ymin, xmax, ymax) of an image's warped pixel-centre corners under H."""
    pts = _dehom(np.asarray(H, dtype=float), _corners(size))
    return (float(pts[:, 0].min()), float(pts[:, 1].min()),
            float(pts[:, 0].max()), float(pts[:, 1].max()))


def _fit_canvas(rig: _Rig, size1: tuple[int, int], size2: tuple[int, int], *, stereo_aware: bool,
                out_size: tuple[int, int] | None = None) -> tuple[_Rig, tuple[int, int]]:
    """Translate both images (same offset) onto one canvas and return its (width, height).

    ``stereo_aware=False`` is RectifKit's smallest common bounding box of both warped images.
    ``stereo_aware=True`` (used once disparities are known to be >= 0) keeps only what can be
    matched: rows both images cover, and columns from the leftmost content of either image to the
    right edge of the left image (right-image content further right could only match left pixels
    with negative disparity). Sides are capped at MAX_CANVAS_SCALE times the input's largest side,
    cropping around the left image's centre. ``out_size`` forces the canvas size instead.
    """
    b1 = warped_bounds(rig.homography(1), size1)
    b2 = warped_bounds(rig.homography(2), size2)
    if stereo_aware:
        x0, x1 = min(b1[0], b2[0]), b1[2]
        y0, y1 = max(b1[1], b2[1]), min(b1[3], b2[3])
        if y1 < y0:
            raise StereoError("the rectified views share no rows: the two images do not overlap")
    else:
        x0, y0 = min(b1[0], b2[0]), min(b1[1], b2[1])
        x1, y1 = max(b1[2], b2[2]), max(b1[3], b2[3])
    centre = _dehom(rig.homography(1), _centre_of(size1)[None])[0]
    cap = int(MAX_CANVAS_SCALE * max(*size1, *size2))
    forced = (None, None) if out_size is None else (int(out_size[0]), int(out_size[1]))
    span = max(x1 - x0, y1 - y0) + 1
    x0, w = _axis_window(x0, x1, centre[0], cap, forced[0])
    y0, h = _axis_window(y0, y1, centre[1], cap, forced[1])
    if out_size is None and span > cap:
        log.warning("rectified canvas capped at %dx%d px (%.1fx the input's largest side)",
                    w, h, MAX_CANVAS_SCALE)
    return rig.shifted((-x0, -y0), (-x0, -y0)), (w, h)


def _axis_window(lo: float, hi: float, centre: float, cap: int,
                 forced: int | None) -> tuple[float, int]:
    """Start coordinate and length of the canvas along one axis (pixel-centre coordinates)."""
    n = int(math.floor(hi - lo)) + 1
    if forced is not None:
        if forced < 1:
            raise StereoError(f"out_size must be positive, got {forced}")
        return (lo + hi) / 2.0 - (forced - 1) / 2.0, forced
    if n <= cap:
        return lo, n
    start = min(max(centre - (cap - 1) / 2.0, lo), hi - (cap - 1))
    return start, cap


def fusiello(P1: np.ndarray, P2: np.ndarray, *, image_size: tuple[int, int] | None = None,
             square_pixels: bool = True) -> Rectification:
    """Rectify two cameras given by 3x4 PPMs; camera 1 becomes the left one.

    With ``image_size`` (width, height), each warped image is centred (RectifKit) and both are
    placed on their smallest common bounding box; without it the homographies are the paper's
    bare ``Qn Qo^-1`` with ``An = (A1 + A2) / 2``. ``square_pixels=False`` keeps the paper's
    averaged fy (then Q needs the generalised second row, see :class:`StereoGeometry`).
    Raises StereoError for a baseline within MIN_BASELINE_ANGLE_DEG of the optical axis, a zero
    baseline or a singular PPM. Invariant to scaling either PPM by any non-zero factor.
    """
    rig = _solve(P1, P2, square_pixels=square_pixels)
    if image_size is not None:
        size = (int(image_size[0]), int(image_size[1]))
        rig, _ = _fit_canvas(_centre(rig, size, size), size, size, stereo_aware=False)
    return rig.rectification()


# ----------------------------------------------------------------------------------------------
# Geometry of a rectified pair (what triangulation needs: :class:`.rectified.StereoGeometry`)
# ----------------------------------------------------------------------------------------------
def _geometry(rig: _Rig, size: tuple[int, int]) -> StereoGeometry:
    return StereoGeometry(
        fx=float(rig.An1[0, 0]), fy=float(rig.An1[1, 1]), cx_left=float(rig.An1[0, 2]),
        cx_right=float(rig.An2[0, 2]), cy=float(rig.An1[1, 2]),
        baseline=float(np.linalg.norm(rig.c2 - rig.c1)), size=size, R_rect=rig.Rn,
        c_left=rig.c1, c_right=rig.c2)


# ----------------------------------------------------------------------------------------------
# Image-level rectification from poses
# ----------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class _View:
    intrinsics: Intrinsics
    T_base_camera: np.ndarray

    @property
    def ppm(self) -> np.ndarray:
        return self.intrinsics.projection(invert(self.T_base_camera))


def second_view_is_left(T_base_cam1: np.ndarray, T_base_cam2: np.ndarray) -> bool:
    """True when view 2 should be the left image (rectified images then turn by <= 90 deg).

    The baseline c2 - c1 seen in camera 1 has image-plane angle atan2(y, x); view 1 stays left
    when that angle lies in (-90, 90] deg (view 2 to the right, or straight below in the image).
    """
    b = T_base_cam1[:3, :3].T @ (T_base_cam2[:3, 3] - T_base_cam1[:3, 3])
    angle = math.degrees(math.atan2(b[1], b[0]))
    return not (-90.0 < angle <= 90.0)


@dataclass(frozen=True)
class RectificationPlan:
    """Two posed views, checked once, with the rectification they share solved once.

    :meth:`from_views` checks both poses, picks the left view (:func:`second_view_is_left`) and
    solves Fusiello's rotation and new intrinsics, centred (RectifKit); :meth:`geometry` (for
    a depth range and canvas) and :meth:`rectify` (the images) reuse that. So a caller that
    first chooses a depth range from the geometry and then rectifies plans the pair once.
    """

    left: _View
    right: _View
    swapped: bool  # True when view 2 is the left one
    rig: _Rig  # centred, before any depth shift or canvas

    @classmethod
    def from_views(cls, intrinsics1: Intrinsics, T_base_cam1: np.ndarray,
                   intrinsics2: Intrinsics, T_base_cam2: np.ndarray, *,
                   snap: bool = False) -> RectificationPlan:
        """The plan of views 1 and 2 (``T_base_cam``: camera_optical in base, m). ``snap``:
        rotations a little off orthonormal are re-orthonormalized (input edges,
        :func:`armstereo.transforms.as_rigid`). StereoError for a bad pose or a degenerate
        baseline."""
        views = [_View(intr, as_rigid(T, f"T_base_cam{i}", error=StereoError, snap=snap))
                 for i, (intr, T) in enumerate(((intrinsics1, T_base_cam1),
                                                (intrinsics2, T_base_cam2)), start=1)]
        swapped = second_view_is_left(views[0].T_base_camera, views[1].T_base_camera)
        left, right = (views[1], views[0]) if swapped else (views[0], views[1])
        sizes = (left.intrinsics.size, right.intrinsics.size)
        return cls(left, right, swapped,
                   _centre(_solve(left.ppm, right.ppm, square_pixels=True), *sizes))

    @property
    def left_intrinsics(self) -> Intrinsics:
        """The original (unrectified) left camera's intrinsics."""
        return self.left.intrinsics

    @property
    def T_base_left_camera(self) -> np.ndarray:
        """The original left camera's checked pose in base (4x4)."""
        return self.left.T_base_camera

    def geometry(self, *, depth_range: tuple[float, float] | None = None,
                 out_size: tuple[int, int] | None = None) -> StereoGeometry:
        """The rectified geometry :meth:`rectify` produces with these arguments."""
        rig, size = self._fitted(depth_range, out_size)
        return _geometry(rig, size)

    def rectify(self, image1: np.ndarray, image2: np.ndarray, *,
                depth_range: tuple[float, float] | None = None,
                out_size: tuple[int, int] | None = None) -> RectifiedPair:
        """Rectify the views' images (uint8 grey or BGR, in the order of :meth:`from_views`,
        each of its intrinsics' size); arguments as :func:`rectify_pair`'s."""
        images = [_check_image(img, f"image{i}") for i, img in enumerate((image1, image2), 1)]
        img_l, img_r = images[::-1] if self.swapped else images
        for img, view, name in ((img_l, self.left, "left"), (img_r, self.right, "right")):
            if (img.shape[1], img.shape[0]) != view.intrinsics.size:
                raise StereoError(f"the {name} image is {img.shape[1]}x{img.shape[0]}, its "
                                  f"calibration {view.intrinsics.width}x"
                                  f"{view.intrinsics.height}")
        rig, size = self._fitted(depth_range, out_size)
        R_l = rig.Rn @ self.left.T_base_camera[:3, :3]
        maps_l = _remap_maps(self.left, R_l, rig.An1, size)
        maps_r = _remap_maps(self.right, rig.Rn @ self.right.T_base_camera[:3, :3], rig.An2, size)
        out_l, mask_l = _warp(img_l, maps_l, self.left.intrinsics.size)
        out_r, mask_r = _warp(img_r, maps_r, self.right.intrinsics.size)
        rotation = round(math.degrees(math.atan2(R_l[1, 0], R_l[0, 0])), 9) + 0.0  # no "-0"
        log.debug("rectified %dx%d, swapped=%s, rotation %.1f deg, baseline %.4f m", *size,
                  self.swapped, rotation, float(np.linalg.norm(rig.c2 - rig.c1)))
        return RectifiedPair(out_l, out_r, mask_l, mask_r, _geometry(rig, size),
                             rig.rectification(), self.swapped, self.left.intrinsics,
                             self.left.T_base_camera, maps_l, maps_r, rig.angle_deg, rotation)

    def _fitted(self, depth_range: tuple[float, float] | None,
                out_size: tuple[int, int] | None) -> tuple[_Rig, tuple[int, int]]:
        """The rig shifted for ``depth_range`` and placed on its canvas, and the canvas size."""
        rig = self.rig
        sizes = (self.left.intrinsics.size, self.right.intrinsics.size)
        if depth_range is not None:
            # Align the far end of the depth range with disparity 0: the matcher then searches
            # [0, d(near) - d(far)] and nothing it can represent is wasted.
            d_far, _ = _geometry(rig, sizes[0]).disparity_window(*depth_range)
            rig = rig.shifted((0.0, 0.0), (d_far, 0.0))
        return _fit_canvas(rig, *sizes, stereo_aware=depth_range is not None, out_size=out_size)


def rectified_geometry(intrinsics1: Intrinsics, T_base_cam1: np.ndarray,
                       intrinsics2: Intrinsics, T_base_cam2: np.ndarray, *,
                       depth_range: tuple[float, float] | None = None,
                       out_size: tuple[int, int] | None = None) -> tuple[StereoGeometry, bool]:
    """The rectified geometry :func:`rectify_pair` would produce, without touching images.

    Returns ``(geometry, swapped)``. Cheap (a few 3x3 products); used to choose a depth range
    (a caller that then rectifies too plans once with :class:`RectificationPlan`).
    """
    plan = RectificationPlan.from_views(intrinsics1, T_base_cam1, intrinsics2, T_base_cam2)
    return plan.geometry(depth_range=depth_range, out_size=out_size), plan.swapped


def _remap_maps(view: _View, R_cv: np.ndarray, K_new: np.ndarray,
                size: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
    """Float32 maps rectified pixel -> original pixel, lens distortion included.

    OpenCV's map builder ignores skew in the old camera matrix, so a skewed K (only allowed
    without distortion) is split into a skew-free K and a shear folded into R.
    """
    K = view.intrinsics.K
    if K[0, 1] != 0.0:
        if view.intrinsics.has_distortion:
            raise StereoError(f"camera matrix with skew {K[0, 1]:.3g} and lens distortion: "
                              "OpenCV's undistortion model has no skew")
        K0 = K.copy()
        K0[0, 1] = 0.0
        R_cv = R_cv @ np.linalg.solve(K, K0)  # OpenCV inverts (K_new R): source = K0 (R^-1 ...)
        K = K0
    return cv2.initUndistortRectifyMap(K, view.intrinsics.dist, R_cv, K_new, size, cv2.CV_32FC1)


def _warp(image: np.ndarray, maps: tuple[np.ndarray, np.ndarray],
          src_size: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
    """Remap an image (bilinear, black outside) and return it with its validity mask.

    The mask is True where the sampling position lies inside the source's pixel-centre grid
    (up to MAP_TOLERANCE px of float32 rounding), i.e. where bilinear interpolation used source
    pixels only.
    """
    mx, my = maps
    out = cv2.remap(image, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT,
                    borderValue=0)
    lo, hx, hy = -MAP_TOLERANCE, src_size[0] - 1 + MAP_TOLERANCE, src_size[1] - 1 + MAP_TOLERANCE
    mask = (mx >= lo) & (my >= lo) & (mx <= hx) & (my <= hy)
    return out, mask


def _check_image(image: np.ndarray, name: str) -> np.ndarray:
    image = np.asarray(image)
    if image.dtype != np.uint8 or image.ndim not in (2, 3) or image.size == 0 or (
            image.ndim == 3 and image.shape[2] not in (1, 3)):
        raise StereoError(f"{name} must be a non-empty uint8 grey or BGR image, got "
                          f"{image.dtype} {image.shape}")
    return image


def rectify_pair(image1: np.ndarray, image2: np.ndarray, K1: np.ndarray, dist1: np.ndarray | None,
                 T_base_cam1: np.ndarray, K2: np.ndarray, dist2: np.ndarray | None,
                 T_base_cam2: np.ndarray, *, out_size: tuple[int, int] | None = None,
                 depth_range: tuple[float, float] | None = None) -> RectifiedPair:
    """Rectify two images taken from known poses (``T_base_cam``: camera_optical in base, m).

    Distortion (OpenCV coefficients, None = none) is removed in the same remap. Without
    ``depth_range`` the canvas is the RectifKit common bounding box; with ``(near, far)`` (m) the
    right image is shifted so that ``far`` has disparity 0 and the canvas keeps only what can be
    matched (see :func:`_fit_canvas`). ``out_size`` (width, height) forces the canvas size.
    Raises StereoError for bad images/poses, a degenerate baseline or views that do not overlap.
    """
    image1, image2 = _check_image(image1, "image1"), _check_image(image2, "image2")
    plan = RectificationPlan.from_views(_intrinsics(image1, K1, dist1), T_base_cam1,
                                        _intrinsics(image2, K2, dist2), T_base_cam2)
    return plan.rectify(image1, image2, depth_range=depth_range, out_size=out_size)


def _intrinsics(image: np.ndarray, K: np.ndarray, dist: np.ndarray | None) -> Intrinsics:
    dist = np.zeros(5) if dist is None else np.asarray(dist, dtype=float).reshape(-1)
    return Intrinsics(int(image.shape[1]), int(image.shape[0]), np.asarray(K, dtype=float), dist)
