"""Height map (max per cell, unknown marked) and the planner's occupancy grid."""

from __future__ import annotations

import io

import numpy as np
import pytest

from armstereo.errors import ConfigError
from armstereo.scene.heightmap import FREE, OCCUPIED, UNKNOWN, height_map, occupancy


def _uvh():
    """A 10 x 6 cm patch at h = 0 with a 2 x 2 cm, 5 cm tall block and a 1 cm hole."""
    g = np.arange(0.0005, 0.1, 0.001)
    x, y = np.meshgrid(g, g[:60])
    x, y = x.ravel(), y.ravel()
    h = np.where((x > 0.02) & (x < 0.04) & (y > 0.02) & (y < 0.04), 0.05, 0.0)
    hole = (x > 0.07) & (x < 0.08) & (y > 0.03) & (y < 0.04)
    return np.column_stack([x, y, h])[~hole]


def test_cells_hold_the_highest_point_and_unseen_cells_are_nan():
    hm = height_map(_uvh(), np.eye(4), 0.005)
    assert hm.heights.shape == (12, 20)  # rows along v, columns along u
    assert hm.origin_uv == (0.0, 0.0)
    assert np.nanmax(hm.heights) == pytest.approx(0.05)
    r, c = hm.cell_of(np.array([[0.03, 0.03], [0.075, 0.035], [0.01, 0.01]]))
    assert hm.heights[r[0], c[0]] == pytest.approx(0.05)
    assert np.isnan(hm.heights[r[1], c[1]])
    assert hm.heights[r[2], c[2]] == pytest.approx(0.0)
    assert hm.known_share == pytest.approx(1 - 4 / 240)


def test_grid_pose_puts_the_corner_in_the_base_frame():
    T = np.eye(4)
    T[:3, 3] = (1.0, 2.0, 0.5)
    hm = height_map(_uvh() + (0.0123, 0.0, 0.0), T, 0.005)
    assert hm.origin_uv[0] == pytest.approx(0.010)  # snapped to a multiple of the cell
    assert np.allclose(hm.T_base_grid[:3, 3], (1.010, 2.0, 0.5))


def test_occupancy_columns_are_occupied_up_to_the_top_free_above_unknown_unseen():
    hm = height_map(_uvh(), np.eye(4), 0.005)
    occ = occupancy(hm, 0.02, min_height=0.01)
    nz, ny, nx = occ.grid.shape
    assert (ny, nx) == (3, 5) and occ.cell_m == pytest.approx(0.02)
    assert nz == 4  # the 5 cm block plus one free voxel above
    assert np.all(occ.grid[:3, 1, 1] == OCCUPIED) and occ.grid[3, 1, 1] == FREE
    assert np.all(occ.grid[:, 0, 0] == FREE)  # the table itself is below the grid
    assert set(np.unique(occ.grid)) <= {UNKNOWN, FREE, OCCUPIED}
    hole_only = height_map(_uvh()[_uvh()[:, 0] < 0.06], np.eye(4), 0.005)
    padded = occupancy(hole_only, 0.02)
    assert padded.grid.shape[1:] == (3, 3)


def test_a_column_seen_nowhere_is_unknown_and_npz_has_the_documented_keys():
    pts = _uvh()
    pts = pts[~((pts[:, 0] > 0.08) & (pts[:, 1] < 0.02))]  # a 2 x 2 cm corner unseen
    occ = occupancy(height_map(pts, np.eye(4), 0.005), 0.02)
    assert np.all(occ.grid[:, 0, 4] == UNKNOWN)
    data = np.load(io.BytesIO(occ.npz_bytes()))
    assert set(data.files) == {"occupancy", "cell_m", "T_base_grid", "values"}
    assert data["occupancy"].dtype == np.int8 and data["T_base_grid"].shape == (4, 4)


def test_bad_cells_are_refused():
    with pytest.raises(ConfigError, match="positive"):
        height_map(_uvh(), np.eye(4), 0.0)
    with pytest.raises(ConfigError, match="larger --cell"):
        height_map(np.array([[0, 0, 0], [500.0, 500.0, 0]]), np.eye(4), 0.0001)
