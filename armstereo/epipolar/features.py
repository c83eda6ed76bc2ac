"""Point features and putative matches between two images.

Three detectors, one result type (:class:`Matches`, ``(N, 2)`` float64 pixel arrays):

* ``harris`` (the sources' method): Harris corners (``cv2.goodFeaturesToTrack`` with the Harris
  response) refined to sub-pixel positions (``cv2.cornerSubPix``), described by normalised
  grey-level patches and matched by normalised cross-correlation (NCC) inside a search window.
  A pair is kept when it is the best match in both directions (mutual best), its NCC reaches
  ``min_ncc`` and it passes the ratio test on the patch distance ``sqrt(2 (1 - NCC))`` (the
  Euclidean distance between the normalised patches) against the second best candidate.
  Corners found independently in two views of textured surfaces do not mark exactly the same
  point (cornerSubPix is exact only on true corners), so the partner's position is then
  refined to the sub-pixel peak of the NCC surface (:func:`refine_ncc`): on a shifted
  texture the median error drops from 0.2 px to a few hundredths.
  Not invariant to rotation or scale: for views that differ by a turn of the wrist, warp one
  image first (the self-check does, see :mod:`armstereo.epipolar.selfcheck`).
* ``sift`` and ``orb``: OpenCV's detectors and descriptors with the same mutual-best and ratio
  tests (L2 for SIFT, Hamming for ORB). Rotation and scale invariant.

Matches are putative: they contain outliers, which the robust estimators remove.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from armstereo.epipolar.errors import EpipolarError

DETECTORS = ("harris", "sift", "orb")
DEFAULT_MAX_FEATURES = 1000
DEFAULT_RATIO = 0.8  # Lowe's ratio test on descriptor distances
HARRIS_K = 0.04
HARRIS_QUALITY = 0.001  # corner response relative to the strongest one
HARRIS_MIN_DISTANCE_PX = 8
HARRIS_BLOCK = 5  # structure-tensor window (px)
SUBPIX_WINDOW = (5, 5)  # half-sizes for cv2.cornerSubPix: an 11x11 search window
SUBPIX_CRITERIA = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 20, 0.01)
PATCH_RADIUS = 7  # NCC patches are 15x15 px
DEFAULT_MIN_NCC = 0.8
REFINE_ITERATIONS = 2
PATCH_CHUNK = 30000  # map rows per cv2.remap call (its limit is 32767)
DEFAULT_SEARCH_FRACTION = 0.35  # search window half-size as a share of the image width


@dataclass(frozen=True)
class Matches:
    """Putative correspondences: ``x1[i]`` in image 1 matches ``x2[i]`` in image 2 (px).

    ``score`` is the NCC (``harris``, higher is better) or the descriptor distance (``sift``,
    ``orb``, lower is better); ``keypoints`` the number of features found in each image.
    """

    x1: np.ndarray
    x2: np.ndarray
    score: np.ndarray
    detector: str
    keypoints: tuple[int, int]

    def __len__(self) -> int:
        return len(self.x1)

    def subset(self, mask: np.ndarray) -> Matches:
        """The matches where ``mask`` ((N,) bool) is True."""
        return Matches(self.x1[mask], self.x2[mask], self.score[mask], self.detector,
                       self.keypoints)


def grey(image: np.ndarray, name: str = "image") -> np.ndarray:
    """uint8 (H, W) grey version of a grey or BGR uint8 image; raises EpipolarError otherwise."""
    image = np.asarray(image)
    if image.dtype != np.uint8 or image.ndim not in (2, 3) or image.size == 0:
        raise EpipolarError(f"{name} must be a non-empty uint8 grey or BGR image, got "
                            f"{image.dtype} {image.shape}")
    if image.ndim == 2:
        return image
    if image.shape[2] == 1:
        return image[:, :, 0]
    if image.shape[2] != 3:
        raise EpipolarError(f"{name} must have 1 or 3 channels, got {image.shape[2]}")
    return cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)


def match_features(image1: np.ndarray, image2: np.ndarray, detector: str = "harris", *,
                   max_features: int = DEFAULT_MAX_FEATURES, ratio: float = DEFAULT_RATIO,
                   min_ncc: float = DEFAULT_MIN_NCC,
                   search_radius: tuple[float, float] | None = None,
                   mask1: np.ndarray | None = None,
                   mask2: np.ndarray | None = None) -> Matches:
    """Putative matches between two uint8 images (grey or BGR) by ``detector``.

    ``search_radius`` (dx, dy) px bounds how far a match may lie from its partner's position
    (default: :data:`DEFAULT_SEARCH_FRACTION` of the width in both directions); it applies to
    every detector. ``mask1``/``mask2`` ((H, W) bool) restrict where features are looked for.
    ``min_ncc`` applies to ``harris`` only. Raises EpipolarError for bad images or options.
    """
    g1, g2 = grey(image1, "image1"), grey(image2, "image2")
    if detector not in DETECTORS:
        raise EpipolarError(f"unknown detector {detector!r}; choose one of {', '.join(DETECTORS)}")
    if int(max_features) < 8:
        raise EpipolarError(f"max_features must be >= 8, got {max_features}")
    if not 0 < ratio <= 1:
        raise EpipolarError(f"ratio must lie in (0, 1], got {ratio}")
    if search_radius is None:
        r = DEFAULT_SEARCH_FRACTION * max(g1.shape[1], g2.shape[1])
        search_radius = (r, r)
    m1, m2 = _mask(mask1, g1, "mask1"), _mask(mask2, g2, "mask2")
    if detector == "harris":
        return _match_harris(g1, g2, m1, m2, int(max_features), ratio, min_ncc, search_radius)
    return _match_descriptors(g1, g2, m1, m2, detector, int(max_features), ratio, search_radius)


def _mask(mask: np.ndarray | None, image: np.ndarray, name: str) -> np.ndarray | None:
    if mask is None:
        return None
    mask = np.asarray(mask)
    if mask.shape != image.shape:
        raise EpipolarError(f"{name} has shape {mask.shape}, its image {image.shape}")
    return mask.astype(np.uint8) * 255


# ------------------------------------------------------------------------------ Harris + NCC
def harris_corners(image: np.ndarray, max_corners: int = DEFAULT_MAX_FEATURES,
                   mask: np.ndarray | None = None, *, subpixel: bool = True) -> np.ndarray:
    """Harris corners ``(N, 2)`` px of a grey uint8 image, at least a patch radius away from
    the border (so every corner has a full NCC patch); refined to sub-pixel positions by
    ``cv2.cornerSubPix`` unless ``subpixel=False``."""
    pts = cv2.goodFeaturesToTrack(image, max_corners, HARRIS_QUALITY, HARRIS_MIN_DISTANCE_PX,
                                  mask=mask, blockSize=HARRIS_BLOCK, useHarrisDetector=True,
                                  k=HARRIS_K)
    if pts is None:
        return np.zeros((0, 2))
    if subpixel:
        pts = cv2.cornerSubPix(image, pts.astype(np.float32), SUBPIX_WINDOW, (-1, -1),
                               SUBPIX_CRITERIA)
    pts = pts.reshape(-1, 2).astype(float)
    h, w = image.shape
    r = PATCH_RADIUS + 1
    inside = ((pts[:, 0] >= r) & (pts[:, 0] <= w - 1 - r) & (pts[:, 1] >= r)
              & (pts[:, 1] <= h - 1 - r))
    return pts[inside]


def sample_patches(image: np.ndarray, pts: np.ndarray, radius: int) -> np.ndarray:
    """``(N, 2r+1, 2r+1)`` float32 grey values around ``pts`` ((N, 2) px), sampled bilinearly
    at the sub-pixel positions."""
    size = 2 * radius + 1
    if len(pts) == 0:
        return np.zeros((0, size, size), np.float32)
    offs = np.arange(-radius, radius + 1, dtype=np.float32)
    chunk = PATCH_CHUNK // size  # cv2.remap takes fewer than 32767 map rows
    parts = []
    for start in range(0, len(pts), chunk):
        p = pts[start:start + chunk].astype(np.float32)
        mx = np.broadcast_to(p[:, 0, None, None] + offs[None, None, :], (len(p), size, size))
        my = np.broadcast_to(p[:, 1, None, None] + offs[None, :, None], (len(p), size, size))
        parts.append(cv2.remap(image, np.ascontiguousarray(mx.reshape(-1, size)),
                               np.ascontiguousarray(my.reshape(-1, size)), cv2.INTER_LINEAR))
    return np.vstack(parts).astype(np.float32).reshape(len(pts), size, size)


def _normalise(patches: np.ndarray) -> np.ndarray:
    """Flatten the last two axes and make each patch zero-mean, unit-norm (flat ones: zeros)."""
    flat = patches.reshape(*patches.shape[:-2], -1)
    flat = flat - flat.mean(axis=-1, keepdims=True)
    norm = np.sqrt(np.einsum("...p,...p->...", flat, flat))[..., None]
    return np.divide(flat, norm, out=np.zeros_like(flat), where=norm > 1e-6)


def normalised_patches(image: np.ndarray, pts: np.ndarray,
                       radius: int = PATCH_RADIUS) -> np.ndarray:
    """``(N, (2r+1)^2)`` float32 patches around ``pts`` (sampled bilinearly at the sub-pixel
    positions), zero mean and unit norm; flat patches are all zeros (NCC 0 with anything)."""
    return _normalise(sample_patches(image, pts, radius))


def _match_harris(g1, g2, m1, m2, max_features, ratio, min_ncc, search_radius) -> Matches:
    p1 = harris_corners(g1, max_features, m1)
    p2 = harris_corners(g2, max_features, m2)
    if len(p1) == 0 or len(p2) == 0:
        return _empty("harris", (len(p1), len(p2)))
    ncc = normalised_patches(g1, p1) @ normalised_patches(g2, p2).T  # (N1, N2)
    ncc[~_window(p1, p2, search_radius)] = -np.inf
    i, j = _mutual_best(ncc)
    keep = ncc[i, j] >= min_ncc
    i, j = i[keep], j[keep]
    second = _second_best(ncc, i, j)
    dist_best = np.sqrt(np.maximum(2.0 * (1.0 - ncc[i, j]), 0.0))
    dist_second = np.sqrt(np.maximum(2.0 * (1.0 - second), 0.0))
    keep = dist_best < ratio * dist_second
    x1, x2 = p1[i[keep]], refine_ncc(g1, g2, p1[i[keep]], p2[j[keep]])
    return Matches(x1, x2, ncc[i[keep], j[keep]].astype(float), "harris", (len(p1), len(p2)))


def refine_ncc(g1: np.ndarray, g2: np.ndarray, x1: np.ndarray, x2: np.ndarray,
               iterations: int = REFINE_ITERATIONS) -> np.ndarray:
    """Move each ``x2`` ((N, 2) px) to the sub-pixel NCC peak of ``x1``'s patch in ``g2``.

    Each round samples the NCC at the 3x3 offsets of one pixel around the current position,
    fits a quadratic surface and moves to its peak (at most one pixel per round; a surface
    without a peak leaves the point where it is). Points whose patch would leave the image
    keep their position.
    """
    x2 = x2.copy()
    if len(x1) == 0:
        return x2
    ref = normalised_patches(g1, x1)
    offsets = np.array([(dx, dy) for dy in (-1, 0, 1) for dx in (-1, 0, 1)], float)
    A = np.column_stack([offsets[:, 0] ** 2, offsets[:, 1] ** 2, offsets[:, 0] * offsets[:, 1],
                         offsets[:, 0], offsets[:, 1], np.ones(9)])
    fit = np.linalg.pinv(A)  # (6, 9): quadratic coefficients from the 9 samples
    h, w = g2.shape
    r, size = PATCH_RADIUS, 2 * PATCH_RADIUS + 1
    for _ in range(iterations):
        # one patch a pixel wider all round holds the 9 one-pixel-shifted windows
        big = sample_patches(g2, x2, r + 1)
        cand = np.stack([big[:, 1 + dy:1 + dy + size, 1 + dx:1 + dx + size]
                         for dx, dy in offsets.astype(int)], axis=1)
        ncc = np.einsum("nkp,np->nk", _normalise(cand), ref)
        a, b, c, d, e, _ = fit @ ncc.T
        det = 4 * a * b - c * c
        peak = (a < 0) & (det > 0)
        with np.errstate(divide="ignore", invalid="ignore"):
            step = np.column_stack([(c * e - 2 * b * d) / det, (c * d - 2 * a * e) / det])
        step = np.where(peak[:, None], np.clip(step, -1.0, 1.0), 0.0)
        new = x2 + step
        inside = ((new[:, 0] >= r + 2) & (new[:, 0] <= w - 3 - r) & (new[:, 1] >= r + 2)
                  & (new[:, 1] <= h - 3 - r))
        x2[inside] = new[inside]
    return x2


def _window(p1: np.ndarray, p2: np.ndarray, radius: tuple[float, float]) -> np.ndarray:
    """(N1, N2) bool: candidate pairs within the search window."""
    a, b = p1.astype(np.float32), p2.astype(np.float32)
    ok = np.abs(b[None, :, 0] - a[:, None, 0]) <= radius[0]
    ok &= np.abs(b[None, :, 1] - a[:, None, 1]) <= radius[1]
    return ok


def _mutual_best(similarity: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Index pairs (i, j) where j is i's best column and i is j's best row (finite only)."""
    j = np.argmax(similarity, axis=1)
    i = np.arange(similarity.shape[0])
    back = np.argmax(similarity, axis=0)
    ok = (back[j] == i) & np.isfinite(similarity[i, j])
    return i[ok], j[ok]


def _second_best(similarity: np.ndarray, i: np.ndarray, j: np.ndarray) -> np.ndarray:
    """Best similarity of row i (and of column j) other than the pair itself; -inf if none."""
    rows = similarity[i].copy()
    rows[np.arange(len(i)), j] = -np.inf
    cols = similarity[:, j].T.copy()
    cols[np.arange(len(i)), i] = -np.inf
    best = np.maximum(rows.max(axis=1, initial=-np.inf), cols.max(axis=1, initial=-np.inf))
    return best


# ------------------------------------------------------------------------------ SIFT and ORB
def _match_descriptors(g1, g2, m1, m2, detector, max_features, ratio, search_radius) -> Matches:
    if detector == "sift":
        algo = cv2.SIFT_create(nfeatures=max_features)
    else:
        algo = cv2.ORB_create(nfeatures=max_features)
    k1, d1 = algo.detectAndCompute(g1, m1)
    k2, d2 = algo.detectAndCompute(g2, m2)
    if d1 is None or d2 is None or len(k1) < 2 or len(k2) < 2:
        return _empty(detector, (len(k1), len(k2)))
    p1 = np.array([k.pt for k in k1], dtype=float)
    p2 = np.array([k.pt for k in k2], dtype=float)
    dist = _distances(d1, d2, binary=detector == "orb")
    dist[~_window(p1, p2, search_radius)] = np.inf
    i, j = _mutual_best(-dist)
    second = -_second_best(-dist, i, j)
    keep = dist[i, j] < ratio * second
    return Matches(p1[i[keep]], p2[j[keep]], dist[i[keep], j[keep]], detector,
                   (len(p1), len(p2)))


def _distances(d1: np.ndarray, d2: np.ndarray, *, binary: bool) -> np.ndarray:
    """(N1, N2) descriptor distances: Hamming for packed binary (ORB), L2 otherwise (SIFT)."""
    if binary:
        b1 = np.unpackbits(d1, axis=1).astype(np.float32)
        b2 = np.unpackbits(d2, axis=1).astype(np.float32)
        return (b1 @ (1.0 - b2).T + (1.0 - b1) @ b2.T).astype(np.float64)
    a, b = d1.astype(np.float64), d2.astype(np.float64)
    sq = np.sum(a * a, axis=1)[:, None] + np.sum(b * b, axis=1)[None, :] - 2.0 * a @ b.T
    return np.sqrt(np.maximum(sq, 0.0))


def _empty(detector: str, keypoints: tuple[int, int]) -> Matches:
    return Matches(np.zeros((0, 2)), np.zeros((0, 2)), np.zeros(0), detector, keypoints)
