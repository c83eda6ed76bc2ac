"""The top-down picture: the cloud seen from above the plane, objects outlined and labelled.

Pixels are plane coordinates (u to the right, v up; for a level table in the base frame that
is base x to the right and base y up), ``px_m`` per pixel; each pixel shows the colour of the
highest point in it, unknown pixels are black. Objects are outlined with their footprint
rectangle (or fitted circle), numbered, and labelled with their height above the plane;
partial objects (cut by the view) are outlined in orange. The support's hull is drawn in blue.
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from armstereo.scene.analysis import SceneAnalysis, SceneObject
from armstereo.scene.cloud import SceneCloud

MAX_SIDE_PX = 1400
TARGET_SIDE_PX = 900  # small clouds are drawn at whole-number zoom up to about this size
MARGIN_PX = 20
LEGEND_PX = 62
OUTLINE_BGR = (60, 255, 60)
PARTIAL_BGR = (0, 165, 255)
HULL_BGR = (255, 160, 60)
TEXT_BGR = (255, 255, 255)
FONT = cv2.FONT_HERSHEY_SIMPLEX
SCALE_BAR_M = 0.05
DIM = 0.85


def top_down_image(analysis: SceneAnalysis, cloud: SceneCloud) -> np.ndarray:
    """BGR uint8 top view of ``cloud`` with the analysis drawn over it (module doc)."""
    plane = analysis.plane
    uvh = plane.to_plane(cloud.points)
    keep = uvh[:, 2] > -analysis.options.plane_threshold_m
    uvh = uvh[keep]
    colors = (np.full((len(uvh), 3), 200, np.uint8) if cloud.colors_bgr is None
              else cloud.colors_bgr[keep])
    lo, hi = uvh[:, :2].min(axis=0), uvh[:, :2].max(axis=0)
    spacing = math.sqrt(plane.area_m2 / max(plane.inliers, 1))  # the table's point spacing
    side = float((hi - lo).max())
    cell = max(spacing, side / MAX_SIDE_PX)  # one cloud cell per point: no see-through holes
    zoom = max(1, int(TARGET_SIDE_PX * cell / side))
    px = cell / zoom
    w = int(math.ceil((hi[0] - lo[0]) / px)) + 2 * MARGIN_PX
    h = int(math.ceil((hi[1] - lo[1]) / px)) + 2 * MARGIN_PX

    def to_px(uv: np.ndarray) -> np.ndarray:
        """Pixel (x, y) of plane points (N, 2): v grows upwards in the picture."""
        x = (uv[:, 0] - lo[0]) / px + MARGIN_PX
        y = h - 1 - ((uv[:, 1] - lo[1]) / px + MARGIN_PX)
        return np.stack([x, y], axis=1)

    hc, wc = -(-h // zoom), -(-w // zoom)  # the cloud raster, one cell per zoom x zoom pixels
    img = np.zeros((hc, wc, 3), np.uint8)
    p = np.clip(np.floor(to_px(uvh[:, :2]) / zoom).astype(np.int64), 0, [wc - 1, hc - 1])
    flat = p[:, 1] * wc + p[:, 0]
    order = np.lexsort((uvh[:, 2], flat))  # by cell, then height: the last one is the top
    last = np.r_[flat[order][1:] != flat[order][:-1], True]
    top = order[last]
    img.reshape(-1, 3)[flat[top]] = colors[top]
    img = cv2.resize(img, None, fx=zoom, fy=zoom, interpolation=cv2.INTER_NEAREST)[:h, :w]
    img = (img * DIM).astype(np.uint8)  # dim the cloud so the drawing stands out
    hull = np.round(to_px(plane.hull_uv)).astype(np.int32)
    cv2.polylines(img, [hull], True, HULL_BGR, 1, cv2.LINE_AA)
    for o in analysis.objects:
        _draw_object(img, o, plane.to_plane(o.footprint_m)[:, :2], to_px, px)
    return np.vstack([img, _legend(w, px, analysis)])


def _draw_object(img: np.ndarray, o: SceneObject, corners_uv: np.ndarray, to_px, px: float):
    color = PARTIAL_BGR if o.partial else OUTLINE_BGR
    if o.model == "sphere":
        c = to_px(corners_uv.mean(axis=0, keepdims=True))[0]
        cv2.circle(img, tuple(np.round(c).astype(int)), int(round(o.size_m[0] / 2 / px)),
                   color, 2, cv2.LINE_AA)
    corners = np.round(to_px(corners_uv)).astype(np.int32)
    cv2.polylines(img, [corners], True, color, 1 if o.model == "sphere" else 2, cv2.LINE_AA)
    centre = corners.mean(axis=0)
    lines = [f"#{o.id}", f"h {o.height_m * 1000:.0f} mm"]
    for k, text in enumerate(lines):
        (tw, th), _ = cv2.getTextSize(text, FONT, 0.5, 1)
        org = (int(centre[0] - tw / 2), int(centre[1] + (k - 0.5) * (th + 6) + th / 2))
        cv2.putText(img, text, org, FONT, 0.5, (0, 0, 0), 3, cv2.LINE_AA)
        cv2.putText(img, text, org, FONT, 0.5, TEXT_BGR, 1, cv2.LINE_AA)


def _legend(width: int, px: float, analysis: SceneAnalysis) -> np.ndarray:
    bar = np.full((LEGEND_PX, width, 3), 32, np.uint8)
    n = len(analysis.objects)
    texts = [f"top view (x right, y up), {n} object(s), h = top above the plane",
             f"plane rms {analysis.plane.rms_m * 1000:.2f} mm; orange: cut by the view"]
    for k, text in enumerate(texts):
        cv2.putText(bar, text, (8, 17 + 18 * k), FONT, 0.45, TEXT_BGR, 1, cv2.LINE_AA)
    length = int(round(SCALE_BAR_M / px))
    cv2.line(bar, (8, 50), (8 + length, 50), TEXT_BGR, 2)
    cv2.putText(bar, f"{SCALE_BAR_M * 100:.0f} cm", (14 + length, 55), FONT, 0.45, TEXT_BGR, 1,
                cv2.LINE_AA)
    return bar
