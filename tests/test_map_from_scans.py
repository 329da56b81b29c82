import numpy as np
import pytest

from pimm_env.errors import BagError
from pimm_env.mapping.from_scans import ScanMapConfig, map_from_scans


def square_scan(pose: np.ndarray, bearings: np.ndarray, half: float = 3.02) -> np.ndarray:
    """Ranges from ``pose`` to the walls of the square room |x|, |y| <= ``half``; the beams at +-90 deg get no
    return (a door), as a SICK reports one."""
    angles = pose[2] + bearings
    c, s = np.cos(angles), np.sin(angles)
    with np.errstate(divide="ignore"):
        tx = np.where(c > 0, (half - pose[0]) / c, np.where(c < 0, (-half - pose[0]) / c, np.inf))
        ty = np.where(s > 0, (half - pose[1]) / s, np.where(s < 0, (-half - pose[1]) / s, np.inf))
    ranges = np.minimum(tx, ty)
    ranges[np.isclose(np.abs(bearings), np.pi / 2)] = np.inf
    return ranges


def test_walls_are_occupied_the_room_free_and_beyond_the_walls_unknown():
    bearings = np.radians(np.arange(-90.0, 90.5, 1.0))
    poses = np.array([[0.0, 0.0, a] for a in np.radians(np.arange(0.0, 360.0, 30.0))])
    occupancy = map_from_scans(poses, [square_scan(p, bearings) for p in poses], bearings, 80.0, ScanMapConfig())
    grid = occupancy.grid
    rows, cols, _ = grid.cells_of(np.array([[3.02, 0.5], [0.5, -3.02], [1.0, 1.0], [0.0, 0.0], [3.6, 0.5]]))
    assert occupancy.occupied[rows[0], cols[0]] and occupancy.occupied[rows[1], cols[1]]  # the walls
    assert occupancy.free[rows[2], cols[2]] and occupancy.free[rows[3], cols[3]]  # the room
    assert not occupancy.free[rows[4], cols[4]] and not occupancy.occupied[rows[4], cols[4]]  # beyond: unknown
    with pytest.raises(BagError, match="no scan with a true pose"):
        map_from_scans(np.zeros((0, 3)), [], bearings, 80.0, ScanMapConfig())


def test_scan_spacing_tells_a_sparse_log_from_a_dense_one():
    from pimm_env.mapping.from_scans import SPARSE_SCAN_SPACING_M, scan_spacing_m

    dense = np.column_stack([np.arange(0, 10, 0.1), np.zeros(100), np.zeros(100)])
    sparse = np.column_stack([np.arange(0, 10, 0.8), np.zeros(13), np.zeros(13)])
    assert scan_spacing_m(dense) == pytest.approx(0.1) and 0.1 < SPARSE_SCAN_SPACING_M
    assert scan_spacing_m(sparse) == pytest.approx(0.8) and 0.8 > SPARSE_SCAN_SPACING_M
    assert scan_spacing_m(dense[:1]) == 0.0
