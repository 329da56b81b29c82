"""A horizontal grid over the map frame: the common raster of occupancy, clearance and corner maps.

Row 0 is the lowest y, as in numpy indexing of the map; images are flipped only when written.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class GridSpec:
    """``shape`` cells of ``resolution`` metres whose lower-left corner is at ``origin`` (x, y)."""

    origin: tuple[float, float]
    resolution: float
    shape: tuple[int, int]  # (rows along y, cols along x)

    @classmethod
    def covering(cls, lower: np.ndarray, upper: np.ndarray, resolution: float, margin: float = 0.5) -> GridSpec:
        """The smallest grid of ``resolution`` covering the box ``lower``..``upper`` plus ``margin``."""
        origin = np.floor((np.asarray(lower) - margin) / resolution) * resolution
        size = np.ceil((np.asarray(upper) + margin - origin) / resolution).astype(int)
        return cls((float(origin[0]), float(origin[1])), float(resolution), (int(size[1]), int(size[0])))

    def empty_mask(self) -> np.ndarray:
        return np.zeros(self.shape, dtype=bool)

    def cell_centers(self) -> tuple[np.ndarray, np.ndarray]:
        """x and y of every cell centre, each of ``shape``."""
        xs = self.origin[0] + (np.arange(self.shape[1]) + 0.5) * self.resolution
        ys = self.origin[1] + (np.arange(self.shape[0]) + 0.5) * self.resolution
        return np.meshgrid(xs, ys)

    def cells_of(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Row, column and in-bounds flag of the cells holding ``points`` (N, 2)."""
        cols = np.floor((points[:, 0] - self.origin[0]) / self.resolution).astype(int)
        rows = np.floor((points[:, 1] - self.origin[1]) / self.resolution).astype(int)
        valid = (rows >= 0) & (rows < self.shape[0]) & (cols >= 0) & (cols < self.shape[1])
        return rows, cols, valid

    def window(self, points: np.ndarray, pad: float = 0.0) -> tuple[slice, slice, np.ndarray, np.ndarray] | None:
        """Slices and cell-centre coordinates of the sub-grid bounding ``points``, or None if outside."""
        lo = points.min(axis=0) - pad
        hi = points.max(axis=0) + pad
        c0 = max(0, int(np.floor((lo[0] - self.origin[0]) / self.resolution)))
        r0 = max(0, int(np.floor((lo[1] - self.origin[1]) / self.resolution)))
        c1 = min(self.shape[1], int(np.ceil((hi[0] - self.origin[0]) / self.resolution)) + 1)
        r1 = min(self.shape[0], int(np.ceil((hi[1] - self.origin[1]) / self.resolution)) + 1)
        if c0 >= c1 or r0 >= r1:
            return None
        xs = self.origin[0] + (np.arange(c0, c1) + 0.5) * self.resolution
        ys = self.origin[1] + (np.arange(r0, r1) + 0.5) * self.resolution
        gx, gy = np.meshgrid(xs, ys)
        return slice(r0, r1), slice(c0, c1), gx, gy

    def points_in_polygon(self, polygon: np.ndarray) -> np.ndarray:
        """Mask of the cells whose centre lies inside ``polygon`` (K, 2), by the even-odd rule."""
        gx, gy = self.cell_centers()
        return points_in_ring(gx, gy, polygon)


def points_in_ring(xs: np.ndarray, ys: np.ndarray, ring: np.ndarray) -> np.ndarray:
    """Which points (xs, ys), any shape, lie inside the closed ring (K, 2), by the even-odd rule."""
    inside = np.zeros(np.shape(xs), dtype=bool)
    x0, y0 = ring[:, 0], ring[:, 1]
    x1, y1 = np.roll(x0, -1), np.roll(y0, -1)
    for ax, ay, bx, by in zip(x0, y0, x1, y1, strict=True):
        if ay == by:
            continue
        crosses = (ay > ys) != (by > ys)
        x_cross = ax + (ys - ay) * (bx - ax) / (by - ay)
        inside ^= crosses & (xs < x_cross)
    return inside
