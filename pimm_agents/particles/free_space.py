"""The free cells of an occupancy grid: whether poses lie in them, and poses drawn uniform over them."""

from __future__ import annotations

import numpy as np

from pimm_env.errors import LocalizerError
from pimm_env.mapping.occupancy import OccupancyGrid


class FreeSpace:
    """The free cells of ``occupancy``; ``sample`` draws poses uniform over them and over heading."""

    def __init__(self, occupancy: OccupancyGrid) -> None:
        rows, cols = np.nonzero(occupancy.free)
        if rows.size == 0:
            raise LocalizerError("the occupancy map has no free cell to place particles in")
        self.grid = occupancy.grid
        self._rows, self._cols = rows, cols
        self._free_flat = occupancy.free.ravel().copy()

    def __len__(self) -> int:
        return self._rows.size

    def contains(self, poses: np.ndarray) -> np.ndarray:
        """Per pose (N, >= 2): whether it lies in a free cell of the map."""
        grid = self.grid
        inv = 1.0 / grid.resolution
        col = ((poses[:, 0] - grid.origin[0]) * inv).astype(np.int64)
        row = ((poses[:, 1] - grid.origin[1]) * inv).astype(np.int64)
        inside = (col >= 0) & (col < grid.shape[1]) & (row >= 0) & (row < grid.shape[0])
        flat = np.where(inside, row * grid.shape[1] + col, 0)
        return inside & self._free_flat[flat]

    def sample(self, n: int, rng: np.random.Generator) -> np.ndarray:
        """``n`` poses (x, y, theta): a random free cell, a uniform point inside it, a uniform heading."""
        pick = rng.integers(0, self._rows.size, n)
        res = self.grid.resolution
        x = self.grid.origin[0] + (self._cols[pick] + rng.random(n)) * res
        y = self.grid.origin[1] + (self._rows[pick] + rng.random(n)) * res
        return np.stack([x, y, rng.uniform(-np.pi, np.pi, n)], axis=1)
