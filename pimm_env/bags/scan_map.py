"""An occupancy map from a bag: its 2D scans laid at its true poses (mapping/from_scans.py)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from pimm_env.bags.read import read_steps
from pimm_env.envs.sim_config import SimConfig
from pimm_env.errors import BagError
from pimm_env.mapping.from_scans import ScanMapConfig, map_from_scans
from pimm_env.mapping.occupancy import OccupancyGrid
from pimm_env.sim.lidar import beam_bearings_2d


def map_from_bag(bag: Path, topics, lidar2d, config: ScanMapConfig | None = None) -> tuple[OccupancyGrid, np.ndarray]:
    """The map of a bag's scans at its true poses (every step with a fresh scan and a truth), and those poses."""
    poses, scans = [], []
    for step in read_steps(Path(bag), topics, lidar2d, SimConfig().lidar3d):
        if step.fresh_scan and step.true_pose is not None:
            poses.append(step.true_pose)
            scan = np.asarray(step.obs["scan"], dtype=float)
            scans.append(np.where(scan >= lidar2d.max_range, np.inf, scan))
    if not poses:
        raise BagError(f"{bag}: no scan arrived with a true pose ({topics.truth}): nothing to build a map from")
    taken = np.array(poses)
    occupancy = map_from_scans(taken, scans, beam_bearings_2d(lidar2d), lidar2d.max_range, config or ScanMapConfig())
    return occupancy, taken
