"""An occupancy map from a bag's 2D scans laid at its true poses (a log's SLAM-corrected poses, say).

Each beam marks the cell of its return as hit and the cells it crossed before it as passed (up to
``free_range_m``; a beam with no return marks nothing); a cell is occupied when at least ``min_hits`` returns
fell in it and they are at least ``occupied_ratio`` of the beams that reached it, free when beams passed it and
it is not occupied, unknown otherwise. A map built from the very log a localizer then replays flatters the
localizer: its walls are where that log's scans saw them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pimm_env.errors import BagError
from pimm_env.mapping.occupancy import OccupancyGrid
from pimm_env.world.grid import GridSpec


@dataclass(frozen=True)
class ScanMapConfig:
    """Ours: a 5 cm grid, as the maps the project derives."""

    resolution: float = 0.05
    min_hits: int = 2
    occupied_ratio: float = 0.3
    free_range_m: float = 20.0  # how far a far return clears space
    #: a beam with no return clears nothing: it may have met glass or a black surface as well as open space


def map_from_scans(
    poses: np.ndarray, scans: list[np.ndarray], bearings: np.ndarray, max_range: float, config: ScanMapConfig
) -> OccupancyGrid:
    """The map of ``scans`` (each (B,) ranges, +inf or >= ``max_range`` for no return) taken at ``poses``
    (S, 3) with beams at ``bearings`` (B,) in the robot's frame."""
    if len(poses) == 0:
        raise BagError("no scan with a true pose to build a map from")
    res = config.resolution
    hits_xy, passed_xy = [], []
    for pose, ranges in zip(poses, scans, strict=True):
        angles = pose[2] + bearings
        returned = np.isfinite(ranges) & (ranges < max_range)
        reach = np.minimum(np.where(returned, ranges, 0.0), config.free_range_m)
        hit_r = ranges[returned & (ranges <= config.free_range_m)]
        hit_a = angles[returned & (ranges <= config.free_range_m)]
        hits_xy.append(pose[:2] + np.column_stack([hit_r * np.cos(hit_a), hit_r * np.sin(hit_a)]))
        steps = np.arange(0.0, config.free_range_m, res / 2)
        along = steps[None, :] < (reach[:, None] - res)  # up to a cell short of the return
        r = np.broadcast_to(steps, along.shape)[along]
        a = np.broadcast_to(angles[:, None], along.shape)[along]
        passed_xy.append(pose[:2] + np.column_stack([r * np.cos(a), r * np.sin(a)]))
    hits, passed = np.vstack(hits_xy), np.vstack(passed_xy)
    everything = np.vstack([hits, passed, poses[:, :2]])
    grid = GridSpec.covering(everything.min(axis=0), everything.max(axis=0), res, margin=1.0)
    hit_count = _count(grid, hits)
    pass_count = _count(grid, passed)
    occupied = (hit_count >= config.min_hits) & (hit_count >= config.occupied_ratio * (hit_count + pass_count))
    free = (pass_count > 0) & ~occupied
    return OccupancyGrid(grid, occupied, free)


def _count(grid: GridSpec, points: np.ndarray) -> np.ndarray:
    rows, cols, valid = grid.cells_of(points)
    flat = np.bincount(rows[valid] * grid.shape[1] + cols[valid], minlength=grid.shape[0] * grid.shape[1])
    return flat.reshape(grid.shape)


#: scans farther apart than this (m driven between scans, on average) make a sparse log
SPARSE_SCAN_SPACING_M = 0.5


def scan_spacing_m(poses: np.ndarray) -> float:
    """The mean distance driven between consecutive scans taken at ``poses`` (K, >= 2)."""
    if len(poses) < 2:
        return 0.0
    steps = np.linalg.norm(np.diff(np.asarray(poses)[:, :2], axis=0), axis=1)
    return float(steps.sum() / (len(poses) - 1))
