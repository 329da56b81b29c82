"""Nearest map corner of any point, by a precomputed grid: the particle filter's data association at O(1)."""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from pimm_env.mapping.corner_map import CornerMap


class NearestCornerGrid:
    """For each cell of a grid covering the corners (plus ``margin``), the index of the nearest corner.

    Points outside the grid take the answer of the nearest edge cell; the filter then measures the real
    distance to that corner, so only the choice of corner is approximate there, and it is far from any.
    """

    def __init__(self, corners: CornerMap, resolution: float = 0.1, margin: float = 12.0) -> None:
        if len(corners) == 0:
            raise ValueError("the corner map is empty: the feature filter has nothing to match corners against")
        if resolution <= 0:
            raise ValueError(f"lookup grid resolution must be positive, got {resolution}")
        self.xy = np.asarray(corners.xy, dtype=np.float64)
        self.theta = np.asarray(corners.theta, dtype=np.float64)
        self.resolution = resolution
        self.origin = self.xy.min(axis=0) - margin
        upper = self.xy.max(axis=0) + margin
        self.shape = tuple(np.ceil((upper - self.origin) / resolution).astype(int)[::-1])  # rows (y), cols (x)
        ys = self.origin[1] + (np.arange(self.shape[0]) + 0.5) * resolution
        xs = self.origin[0] + (np.arange(self.shape[1]) + 0.5) * resolution
        gx, gy = np.meshgrid(xs, ys)
        _, index = cKDTree(self.xy).query(np.column_stack([gx.ravel(), gy.ravel()]))
        self.table = index.astype(np.int32).reshape(self.shape)
        # per cell, the nearest corner's x, y and theta: one gather each in the filter's hot loop
        # x + iy packed in one complex number: one gather gives both coordinates
        self.cell_xy = (self.xy[index, 0] + 1j * self.xy[index, 1]).astype(np.complex64)
        self.cell_theta = self.theta[index].astype(np.float32)

    def cells(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Flat cell index (into ``cell_xy``, ``cell_theta``) of points ``x``, ``y`` (float32 for speed).

        Points inside the grid get their cell. Points outside get some valid cell, not always the nearest
        edge one; the filter measures the true distance to that cell's corner, so such a point (more than
        ``margin`` from every corner) only ever scores low, as it should.
        """
        inv = np.float32(1.0 / self.resolution)
        flat = np.floor((y - np.float32(self.origin[1])) * inv)
        flat *= np.float32(self.shape[1])
        flat += (x - np.float32(self.origin[0])) * inv
        np.clip(flat, 0, self.table.size - 1, out=flat)
        return flat.astype(np.int32)

    def nearest(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Index of the nearest corner for points ``x``, ``y`` of any (equal) shape, inside the grid."""
        return self.table.ravel()[self.cells(x, y)]
