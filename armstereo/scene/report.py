"""Text for people: the object table and a summary of an analysis (and of its score)."""

from __future__ import annotations

from armstereo.scene.analysis import SceneAnalysis

MM = 1000.0


def object_table(analysis: SceneAnalysis, *, markdown: bool = False) -> list[str]:
    """One line per object: id, centre, size, yaw, height, points, model (mm, degrees)."""
    head = ["id", "centre x, y, z (mm)", "L x W x H (mm)", "yaw (deg)", "height (mm)",
            "points", "model"]
    rows = []
    for o in analysis.objects:
        x, y, z = (v * MM for v in o.center_m)
        L, W, H = (v * MM for v in o.size_m)
        model = o.model + (", partial" if o.partial else "")
        rows.append([str(o.id), f"{x:.1f}, {y:.1f}, {z:.1f}", f"{L:.1f} x {W:.1f} x {H:.1f}",
                     f"{o.yaw_deg:.1f}", f"{o.height_m * MM:.1f}", str(o.points), model])
    if markdown:
        lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
        return lines + ["| " + " | ".join(r) + " |" for r in rows]
    widths = [max(len(r[k]) for r in [head, *rows]) for k in range(len(head))]
    return ["  ".join(c.rjust(w) for c, w in zip(r, widths, strict=True))
            for r in [head, *rows]]


def summary(analysis: SceneAnalysis) -> list[str]:
    """Plane, object count, table, maps and timings, as lines."""
    pl, hm, occ = analysis.plane, analysis.height_map, analysis.occupancy
    n = pl.normal
    lines = [f"plane:   normal [{n[0]:.4f}, {n[1]:.4f}, {n[2]:.4f}] (tilt {pl.tilt_deg:.3f} deg "
             f"from up), height {pl.height_m * MM:.2f} mm, rms {pl.rms_m * MM:.2f} mm, "
             f"{pl.inliers:,} inliers, {pl.area_m2:.3f} m^2 seen",
             f"objects: {len(analysis.objects)} ({analysis.rejected_clusters} small clusters "
             "rejected as noise)"]
    lines += ["  " + line for line in object_table(analysis)]
    nz, ny, nx = occ.grid.shape
    lines.append(f"maps:    height map {hm.heights.shape[1]} x {hm.heights.shape[0]} cells of "
                 f"{hm.cell_m * MM:g} mm ({hm.known_share:.0%} known); occupancy "
                 f"{nx} x {ny} x {nz} voxels of {occ.cell_m * MM:g} mm")
    t = analysis.timings_s
    lines.append("time:    " + ", ".join(f"{k} {v:.2f} s" for k, v in t.items())
                 + f"; total {sum(t.values()):.2f} s")
    return lines


def score_lines(score) -> list[str]:
    """A :class:`~armstereo.evaluation.scene_score.SceneScore` as lines."""
    lines = [f"score:   plane tilt {score.plane_tilt_deg:.3f} deg, height error "
             f"{score.plane_height_error_m * MM:+.2f} mm; {len(score.matched)} of "
             f"{score.true_objects} objects found, missed: {', '.join(score.missed) or 'none'}, "
             f"phantoms: {', '.join(map(str, score.phantoms)) or 'none'}"]
    for m in score.matched:
        yaw = "" if m.yaw_error_deg is None else f", yaw {m.yaw_error_deg:+.1f} deg"
        lines.append(f"  {m.name:<8} #{m.found_id}: centre {m.center_error_m * MM:.1f} mm, "
                     f"length {m.length_error_m * MM:+.1f}, width {m.width_error_m * MM:+.1f}, "
                     f"height {m.height_error_m * MM:+.1f} mm{yaw}"
                     + (" (partial: cut by the view)" if m.partial else ""))
    return lines
