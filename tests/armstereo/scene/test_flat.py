"""Flat objects: sheets below the object band, found from table cells' median heights."""

from __future__ import annotations

import numpy as np
import pytest

from armstereo.errors import ConfigError
from armstereo.evaluation.scene_score import score_scene
from armstereo.evaluation.scene_truth import SceneTruth
from armstereo.scene import SceneOptions, analyze_scene
from armstereo.scene.flat import cell_medians, flat_regions
from armstereo.scene.synthetic import box, scan, table

# a sheet as thick as the realistic desk's notes pad, and a tall box beside it; per-point
# noise of 1.5 mm (a stereo cloud's table, well above the sheet's thickness)
SHEET = box("sheet", 0.08, 0.06, 0.20, 0.14, 0.002, yaw_deg=-8.0)
CRATE = box("crate", -0.12, -0.08, 0.10, 0.08, 0.06)
NOISE = 0.0015


def _cloud(*objects, seed: int = 0):
    truth = SceneTruth([table(), *objects], "table")
    return truth, scan(truth, spacing=0.002, noise=NOISE, seed=seed)


def _inside_sheet(xy: np.ndarray, grow: float = 0.0) -> np.ndarray:
    T = SHEET.T_base_local
    local = (xy - T[:2, 3]) @ T[:2, :2]
    return ((np.abs(local[:, 0]) <= SHEET.dims[0] / 2 + grow)
            & (np.abs(local[:, 1]) <= SHEET.dims[1] / 2 + grow))


def _regions(points: np.ndarray, **kw) -> list[np.ndarray]:
    args = dict(cell_m=0.02, height_m=0.001, band_m=0.005, margin_m=0.03, min_area_m2=0.01)
    args.update(kw)
    return flat_regions(points, **args)  # a level table at z = 0: plane coordinates = base


def test_cell_medians_are_the_median_heights_of_full_cells():
    uvh = np.array([[0.001, 0.001, h] for h in range(12)] + [[0.031, 0.001, 5.0]], float)
    med, flat, shape = cell_medians(uvh, 0.02)
    assert tuple(shape) == (2, 1) and med[0, 0] == 6.0 and np.isnan(med[1, 0])
    assert flat.tolist() == [0] * 12 + [1]


def test_a_sheet_is_one_region_covering_its_footprint():
    _, cloud = _cloud(SHEET, CRATE)
    regions = _regions(cloud.points)
    assert len(regions) == 1
    xy = cloud.points[regions[0], :2]
    assert np.mean(_inside_sheet(xy, grow=0.02)) > 0.97  # the region is the sheet ...
    inside = np.count_nonzero(_inside_sheet(cloud.points[:, :2], grow=-0.02))
    assert np.count_nonzero(_inside_sheet(xy, grow=-0.02)) > 0.95 * inside  # ... all of it


def test_bare_noisy_table_and_small_patches_make_no_region():
    for seed in range(3):
        _, cloud = _cloud(CRATE, seed=seed)
        assert _regions(cloud.points) == []
    # a coaster: raised like the sheet, but below the area a flat object needs
    _, cloud = _cloud(box("coaster", 0.08, 0.06, 0.08, 0.08, 0.002), CRATE)
    assert _regions(cloud.points) == []
    assert len(_regions(cloud.points, min_area_m2=0.004)) == 1


def test_a_sheet_next_to_an_object_is_kept_apart_from_it():
    # the crate's own rim cells (and a matcher's fattening there) stand in the band: cells
    # within the margin of them never join a flat region
    near = box("crate", 0.08 + 0.16, 0.06, 0.10, 0.08, 0.06)
    _, cloud = _cloud(SHEET, near)
    regions = _regions(cloud.points)
    assert len(regions) == 1
    assert np.max(cloud.points[regions[0], 2]) < 0.02


def test_the_analysis_reports_the_sheet_as_a_flat_object():
    truth, cloud = _cloud(SHEET, CRATE)
    analysis = analyze_scene(cloud)
    score = score_scene(analysis, truth)
    assert not score.missed and not score.phantoms and len(score.matched) == 2
    sheet = next(analysis.objects[m.found_id] for m in score.matched if m.name == "sheet")
    assert sheet.top == "flat" and abs(sheet.height_m - 0.002) < 0.0005
    assert abs(sheet.size_m[0] - 0.20) < 0.03 and abs(sheet.size_m[1] - 0.14) < 0.03
    assert abs(score.plane_height_error_m) < 2e-4
    off = score_scene(analyze_scene(cloud, SceneOptions(flat_min_area_m2=0.0)), truth)
    assert list(off.missed) == ["sheet"] and not off.phantoms


@pytest.mark.parametrize("name", ["flat_min_area_m2", "flat_height_m", "flat_margin_m"])
def test_negative_flat_options_are_refused(name):
    with pytest.raises(ConfigError, match=name):
        SceneOptions(**{name: -0.01}).check()


def test_flat_cell_must_be_positive_when_flat_objects_are_searched():
    with pytest.raises(ConfigError, match="flat_cell_m"):
        SceneOptions(flat_cell_m=0.0).check()
    SceneOptions(flat_cell_m=0.0, flat_min_area_m2=0.0).check()
