"""Uniform sampling of poses over the free cells of an occupancy grid."""

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

    def __len__(self) -> int:
        return self._rows.size

    def sample(self, n: int, rng: np.random.Generator) -> np.ndarray:
        """``n`` poses (x, y, theta): a random free cell, a uniform point inside it, a uniform heading."""
        pick = rng.integers(0, self._rows.size, n)
        res = self.grid.resolution
        x = self.grid.origin[0] + (self._cols[pick] + rng.random(n)) * res
        y = self.grid.origin[1] + (self._rows[pick] + rng.random(n)) * res
        return np.stack([x, y, rng.uniform(-np.pi, np.pi, n)], axis=1)
