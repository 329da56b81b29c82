"""What the run, bag and AMCL tests share: a small room's routes, the plugin localizers, and a box room with the
observation an AMCL reads."""

import numpy as np

from pimm_env.mapping.occupancy import OccupancyGrid
from pimm_env.world.grid import GridSpec

ROUTES = """
format: pimm-scenarios/1
scenarios:
  there:
    start: [1.0, 1.0, 0.0]
    waypoints: [[1.0, 1.0], [3.5, 1.0], [3.5, 3.0]]
    speed: 0.5
  there_kidnap:
    base: there
    kidnap_to: [1.0, 3.0, 0.0]
"""
AMCL = {"max_particles": 300, "min_particles": 100}
READER = "tests.plugins.dead_reckoning:make_cloud_reader"
DEAD = "tests.plugins.dead_reckoning:make"


def box_room() -> OccupancyGrid:
    """A 4 m x 3 m room at 5 cm with a pillar, so that the scan pins down position and heading."""
    grid = GridSpec((0.0, 0.0), 0.05, (60, 80))
    occupied = grid.empty_mask()
    occupied[[0, -1], :] = True
    occupied[:, [0, -1]] = True
    occupied[10:16, 50:56] = True
    return OccupancyGrid(grid, occupied, ~occupied)


def observation(scan: np.ndarray, odom=(0.0, 0.0, 0.0), t: float = 0.0) -> dict[str, np.ndarray]:
    return {
        "odom": np.array(odom, dtype=np.float32),
        "scan": scan.astype(np.float32),
        "time": np.array([t]),
        "scan_time": np.array([t]),
    }
