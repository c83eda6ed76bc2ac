"""Summaries of a recording for ``armstereo inspect``: a stable JSON form and a text form.

The JSON keys are part of the documented interface (recordings/README.md); add keys, never rename
or remove them.
"""

from __future__ import annotations

import numpy as np

from armstereo.errors import RecordingError
from armstereo.recording.assemble import fk_vs_controller
from armstereo.recording.reader import Recording, View


def summarize(rec: Recording) -> dict:
    """The JSON-ready summary of an opened recording (keys documented in recordings/README.md)."""
    views = {v.index: v for v in rec.views}
    return {
        "file": str(rec.path),
        "size_bytes": rec.size_bytes,
        "indexed": rec.indexed,
        "truncated": rec.truncated,
        "duration_s": rec.duration_s,
        "views": len(rec.views),
        "channels": [{"topic": c.topic, "schema": c.schema, "encoding": c.encoding,
                      "messages": c.messages} for c in rec.channels],
        "pairs": [_pair_entry(views, event) for event in rec.pair_events],
        "calibration": _calibration_entry(rec),
        "metadata": dict(rec.metadata),
        "warnings": list(rec.warnings),
        **_fk_vs_controller(rec),
    }


def _fk_vs_controller(rec: Recording) -> dict:
    """``fk_vs_controller_max_mm`` / ``_deg``: the largest difference between our FK and the
    controller's reported flange pose over the views (null when no view recorded it)."""
    diffs = [d for v in rec.views if (d := fk_vs_controller(v)) is not None]
    if not diffs:
        return {"fk_vs_controller_max_mm": None, "fk_vs_controller_max_deg": None}
    return {"fk_vs_controller_max_mm": max(d[0] for d in diffs) * 1000.0,
            "fk_vs_controller_max_deg": float(np.degrees(max(d[1] for d in diffs)))}


def _pair_entry(views: dict[int, View], event: dict) -> dict:
    left, right = views.get(event["left_view"]), views.get(event["right_view"])
    return {
        "pair": event["pair"], "left_view": event["left_view"],
        "right_view": event["right_view"],
        "commanded_baseline_m": event["commanded_baseline_m"],
        "achieved_baseline_m": event["achieved_baseline_m"],
        "direction": event["direction"],
        "complete": left is not None and right is not None,
        "image_size": _image_size(left) if left is not None else None,
        **({} if event["viewpoint"] is None else {"viewpoint": event["viewpoint"]}),
    }


def _image_size(view: View) -> list[int] | None:
    if view.image_size is not None:
        return list(view.image_size)
    try:  # a format whose header we do not parse: decode it
        h, w = view.image.shape[:2]
    except RecordingError:
        return None
    return [w, h]


def _calibration_entry(rec: Recording) -> dict | None:
    intr = rec.calibration
    if intr is None:
        return None
    info = rec.calibration_info or {}
    return {"width": intr.width, "height": intr.height, "fx": intr.fx, "fy": intr.fy,
            "cx": intr.cx, "cy": intr.cy, "distortion_model": info.get("distortion_model", ""),
            "D": [float(d) for d in intr.dist], "frame_id": info.get("frame_id", "")}


def format_text(summary: dict) -> str:
    """Human-readable form of :func:`summarize`'s result."""
    lines = [_headline(summary), "channels:"]
    rows = [(c["topic"], c["schema"], c["encoding"], str(c["messages"]))
            for c in summary["channels"]]
    widths = [max([len(h)] + [len(r[i]) for r in rows])
              for i, h in enumerate(("topic", "schema", "encoding", "messages"))]
    for row in [("topic", "schema", "encoding", "messages"), *rows]:
        lines.append("  " + "  ".join(cell.ljust(w) if i < 3 else cell.rjust(w)
                                      for i, (cell, w) in enumerate(zip(row, widths,
                                                                        strict=True))))
    lines.append(f"views: {summary['views']} complete")
    lines.append(f"pairs: {len(summary['pairs'])}")
    lines.extend("  " + _pair_line(p) for p in summary["pairs"])
    lines.append("calibration: " + _calibration_line(summary["calibration"]))
    if summary["fk_vs_controller_max_mm"] is not None:
        lines.append(f"FK vs controller: {summary['fk_vs_controller_max_mm']:.4f} mm, "
                     f"{summary['fk_vs_controller_max_deg']:.5f} deg at most over the views")
    lines.append("metadata:" if summary["metadata"] else "metadata: none")
    for key, value in summary["metadata"].items():
        if "\n" in value:  # a multi-line value (e.g. mount_toml) shows its line count only
            value = f"({value.count(chr(10)) + 1} lines; see --json)"
        lines.append(f"  {key}: {value}")
    lines.append(f"warnings: {len(summary['warnings'])}" if summary["warnings"]
                 else "warnings: none")
    lines.extend(f"  - {w}" for w in summary["warnings"])
    return "\n".join(lines)


def _headline(s: dict) -> str:
    state = ("indexed" if s["indexed"] else "no index") + (", truncated" if s["truncated"]
                                                            else "")
    duration = "no messages" if s["duration_s"] is None else f"{s['duration_s']:.3f} s"
    return f"{s['file']}: {s['size_bytes'] / 1e6:.2f} MB, {state}, {duration}"


def _pair_line(p: dict) -> str:
    size = "incomplete" if not p["complete"] else (
        f"{p['image_size'][0]}x{p['image_size'][1]}" if p["image_size"] else "size unknown")
    return (f"pair {p['pair']}: views {p['left_view']},{p['right_view']}  commanded "
            f"{p['commanded_baseline_m'] * 1000:.3f} mm  achieved "
            f"{p['achieved_baseline_m'] * 1000:.3f} mm  direction {p['direction']}  {size}"
            + (f"  viewpoint {p['viewpoint']}" if p.get("viewpoint") is not None else ""))


def _calibration_line(c: dict | None) -> str:
    if c is None:
        return "none"
    dist = "no distortion" if not any(c["D"]) else "D " + ", ".join(f"{d:.4g}" for d in c["D"])
    return (f"{c['width']}x{c['height']}  fx {c['fx']:.2f}  fy {c['fy']:.2f}  cx {c['cx']:.2f}  "
            f"cy {c['cy']:.2f}  {c['distortion_model']} ({dist})")
