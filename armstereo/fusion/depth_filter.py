"""Per-pixel depth variance and a local plane fit of each depth map before it is fused.

Why (bench/results/cell_scan.md, docs/fusion.md): on the realistic cell the pairs' depth error
is not one Gaussian per pair but varies by two orders of magnitude across a map. Where the
texture is weak (the grey table) a pair's depth wanders 3-6 mm in blobs a few pixels wide;
on textured boards it is 0.5-1 mm. A TSDF that gives every pixel the weight 1 lets the bad
pixels decide wherever few pairs overlap. The map itself shows which pixels are bad: the rms
residual of a plane fitted to the depth around a pixel predicted the true error well
(median |error| 0.6 mm where the residual is under 1 mm, 6 mm where it is over 5 mm).

For every valid pixel, a plane in **inverse depth** (exact for a planar surface seen by a
pinhole: 1/z is linear in u, v) is fitted to the valid pixels of a ``window`` x ``window``
square whose depth is within ``edge`` of the centre's (the other side of a depth edge is
another surface and stays out of the fit). The pixel then gets

- the fitted depth at its centre (the mean of its surface's neighbours: noise averaged over
  the window, a plane or a gently curved surface kept), and
- the weight ``sigma0^2 / (sigma0^2 + s^2)``, ``s`` the fit's rms residual in depth (m):
  inverse-variance weighting with a floor ``sigma0`` for what the residual cannot see, so a
  pixel on a smooth patch weighs up to 1 and a pixel in a 5 mm blob about 0.04.

A pixel with fewer than ``min_support`` of the window on its own surface (a speck, a sliver
at an edge) is dropped (NaN): such pixels were mostly the fattened borders of objects.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from armstereo.errors import ConfigError
from armstereo.fusion.tsdf import DepthFrame


@dataclass(frozen=True, kw_only=True)
class DepthFilterOptions:
    """How each depth map is filtered before fusion (see the module docstring). ``window``
    (odd, px), ``sigma0`` (m), ``edge`` (m), ``min_support`` (share of the window);
    ``smooth`` False keeps the matched depth and only weights it; ``enabled`` False fuses the
    depth as matched with weight 1 (the behaviour before this filter)."""

    enabled: bool = True
    smooth: bool = True
    window: int = 15
    sigma0: float = 0.001
    edge: float = 0.010
    min_support: float = 0.25

    def __post_init__(self) -> None:
        if self.window < 3 or self.window % 2 == 0:
            raise ConfigError(f"depth filter window must be odd and >= 3 px, got {self.window}")
        for name in ("sigma0", "edge"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ConfigError(f"depth filter {name} must be > 0 m, got {value}")
        if not 0 < self.min_support <= 1:
            raise ConfigError(f"depth filter min_support must be in (0, 1], got "
                              f"{self.min_support}")

    def record(self) -> dict:
        """The options as the report records them."""
        return dataclasses.asdict(self)


UNFILTERED_METHODS = ("sgbm",)  # matchers whose depth is fused unfiltered by default


def default_filter(method: str | None) -> DepthFilterOptions:
    """The filter a matcher's depth gets by default: on, except for StereoSGBM. SGBM's
    smoothness term leaves its weak-texture errors as smooth, wrong plateaus (median error
    1.3 mm even where its depth varies under 0.5 mm rms in 7 x 7 pixels; 0.5 mm for
    Birchfield-Tomasi): the residual weights trusted them and its fused scan got worse
    (realistic cell, seeds 0-4: 2.89 -> 3.16 mm, 90 -> 83 % complete) where
    Birchfield-Tomasi's went from 2.10 to 1.31 mm."""
    return DepthFilterOptions(enabled=method not in UNFILTERED_METHODS)


def filter_frame(frame: DepthFrame, o: DepthFilterOptions) -> DepthFrame:
    """``frame`` with its depth fitted and weighted (unchanged when ``o.enabled`` is False)."""
    if not o.enabled:
        return frame
    depth, weight = fit_depth(frame.depth, o)
    if not o.smooth:
        depth = np.where(np.isfinite(depth), frame.depth, np.nan).astype(np.float32)
    return dataclasses.replace(frame, depth=depth, weight=weight)


def fit_depth(depth: np.ndarray, o: DepthFilterOptions) -> tuple[np.ndarray, np.ndarray]:
    """(fitted depth (H, W) float32 m, NaN = dropped; weight (H, W) float32 in [0, 1])."""
    d = np.ascontiguousarray(depth, dtype=np.float32)
    if d.ndim != 2:
        raise ConfigError(f"depth must be a 2D array, got shape {d.shape}")
    need = max(3, int(math.ceil(o.min_support * o.window * o.window)))
    return _fit(d, o.window // 2, float(o.edge), float(o.sigma0), need)


@njit(nogil=True, cache=True)
def _fit(depth, half, edge, sigma0, need):
    H, W = depth.shape
    out = np.full((H, W), np.nan, dtype=np.float32)
    weight = np.zeros((H, W), dtype=np.float32)
    m_same = np.zeros(10)
    m_all = np.zeros(10)
    for r in range(H):
        for c in range(W):
            z0 = depth[r, c]
            if not (z0 > 0.0):
                continue
            _moments(depth, r, c, z0, half, edge, m_same, m_all)
            if m_same[0] < need:
                continue
            z_fit, _ = _plane(m_same)
            if not (z_fit > 0.0):
                continue
            _, s = _plane(m_all)
            out[r, c] = z_fit
            weight[r, c] = sigma0 * sigma0 / (sigma0 * sigma0 + s * s)
    return out, weight


@njit(nogil=True, cache=True)
def _moments(depth, r, c, z0, half, edge, m_same, m_all):
    """Sums (n, u, v, q, uu, vv, uv, uq, vq, qq) over the window around (r, c), q = 1/z,
    (u, v) relative to the centre: of the pixels within ``edge`` of z0 and of all valid."""
    H, W = depth.shape
    m_same[:] = 0.0
    m_all[:] = 0.0
    for dr in range(max(-half, -r), min(half, H - 1 - r) + 1):
        for dc in range(max(-half, -c), min(half, W - 1 - c) + 1):
            z = depth[r + dr, c + dc]
            if not (z > 0.0):
                continue
            _add(m_all, float(dc), float(dr), 1.0 / z)
            if abs(z - z0) <= edge:
                _add(m_same, float(dc), float(dr), 1.0 / z)


@njit(nogil=True, cache=True, inline="always")
def _add(m, u, v, q):
    m[0] += 1.0
    m[1] += u
    m[2] += v
    m[3] += q
    m[4] += u * u
    m[5] += v * v
    m[6] += u * v
    m[7] += u * q
    m[8] += v * q
    m[9] += q * q


@njit(nogil=True, cache=True)
def _plane(m):
    """(depth at the centre, rms residual in depth) of the least-squares plane in inverse
    depth through the sums ``m`` (see _moments); (0, 0) for fewer than 3 pixels."""
    n = m[0]
    if n < 3:
        return 0.0, 0.0
    mu, mv, mq = m[1] / n, m[2] / n, m[3] / n
    cuu, cvv, cuv = m[4] / n - mu * mu, m[5] / n - mv * mv, m[6] / n - mu * mv
    cuq, cvq, cqq = m[7] / n - mu * mq, m[8] / n - mv * mq, m[9] / n - mq * mq
    det = cuu * cvv - cuv * cuv
    b = c = 0.0
    if det > 1e-9 * (cuu + cvv) ** 2:  # else the pixels lie on a line: fit a constant
        b = (cvv * cuq - cuv * cvq) / det
        c = (cuu * cvq - cuv * cuq) / det
    q_fit = mq - b * mu - c * mv  # at the centre pixel (du = dv = 0)
    if not (q_fit > 0.0):
        return 0.0, 0.0
    z_fit = 1.0 / q_fit
    ssr = max(cqq - b * cuq - c * cvq, 0.0)
    return z_fit, math.sqrt(ssr) * z_fit * z_fit
