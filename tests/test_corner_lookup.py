import numpy as np
import pytest

from pimm_agents.corners.lookup import NearestCornerGrid
from pimm_env.mapping.corner_map import CornerMap

# A door jamb in a 0.1 m wall along y = 0: the two convex corners on the corridor side and the room side sit
# 0.1 m apart and face opposite ways (bisector headings in the map frame).
JAMB = CornerMap(
    xy=np.array([[0.0, 0.05], [0.0, -0.05], [5.0, 5.0]]),
    z=np.full(3, 3.0),
    theta=np.array([3 * np.pi / 4, -3 * np.pi / 4, 0.0]),
)


def test_position_only_lookup_picks_the_nearest_whatever_its_heading():
    grid = NearestCornerGrid(JAMB, resolution=0.05)
    assert grid.nearest(np.array([0.0]), np.array([0.08]))[0] == 0
    assert grid.nearest(np.array([0.0]), np.array([-0.08]))[0] == 1


def test_orientation_bins_tell_the_two_sides_of_a_jamb_apart():
    grid = NearestCornerGrid(JAMB, resolution=0.25, orientation_bins=8)
    # a corner seen on the room side (heading -3pi/4) whose position lands in a cell nearer the other one
    x, y = np.array([0.0, 0.0]), np.array([0.1, -0.1])
    assert list(grid.nearest(x, y, np.array([-3 * np.pi / 4, -3 * np.pi / 4]))) == [1, 1]
    assert list(grid.nearest(x, y, np.array([3 * np.pi / 4, 3 * np.pi / 4 + 2 * np.pi]))) == [0, 0]  # any turn
    # far corners still win by position: a heading alone does not pull a match 5 m away
    assert grid.nearest(np.array([0.0]), np.array([0.0]), np.array([0.1]))[0] in (0, 1)
    with pytest.raises(ValueError, match="headings"):
        grid.cells(x, y)
    with pytest.raises(ValueError, match="orientation_bins"):
        NearestCornerGrid(JAMB, orientation_bins=0)


@pytest.mark.parametrize("bins", [1, 6, 8])
def test_cells_are_the_clipped_cell_and_the_wrapped_heading_bin_inside_the_grid_and_out(bins):
    grid = NearestCornerGrid(JAMB, resolution=0.25, margin=2.0, orientation_bins=bins)
    rng = np.random.default_rng(0)
    rows, cols = grid.shape
    x = rng.uniform(grid.origin[0] - 3, grid.origin[0] + cols * 0.25 + 3, 5000).astype(np.float32)
    y = rng.uniform(grid.origin[1] - 3, grid.origin[1] + rows * 0.25 + 3, 5000).astype(np.float32)
    theta = rng.uniform(-4 * np.pi, 4 * np.pi, 5000).astype(np.float32)
    # the plain formula: the flat cell, clipped into the grid, then the heading's bin modulo a full turn
    flat = np.floor((y - np.float32(grid.origin[1])) / np.float32(0.25)) * cols
    flat += np.floor((x - np.float32(grid.origin[0])) / np.float32(0.25))
    expected = np.clip(flat, 0, rows * cols - 1).astype(np.int64) * bins
    expected += np.floor(theta * np.float32(bins / (2 * np.pi))).astype(np.int64) % bins
    assert np.array_equal(grid.cells(x, y, theta), expected)
