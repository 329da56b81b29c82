"""Nearest map corner of any point (and heading), by a precomputed grid: the particle filter's data
association at O(1)."""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from pimm_env.errors import LocalizerError
from pimm_env.geometry import wrap_angle
from pimm_env.mapping.corner_map import CornerMap

#: Corners considered per cell when the lookup also weighs orientation (the nearest this many by position).
CANDIDATES = 8


class NearestCornerGrid:
    """For each cell of a grid covering the corners (plus ``margin``), and each of ``orientation_bins``
    headings, the corner that best explains a corner seen there with that heading.

    With one bin that is the nearest corner by position (the thesis's association). With more, the corner
    among the ``CANDIDATES`` nearest that minimizes d^2 / sigma_pos^2 + dtheta^2 / sigma_theta^2 at the
    bin's centre heading: the two sides of a door jamb, 0.1-0.2 m apart and 90-180 deg apart in heading,
    are then told apart, where by position alone a cell picks either and a correct feature scores zero.

    Points outside the grid take the answer of some edge cell; the filter then measures the real distance to
    that corner, so only the choice of corner is approximate there, and it is far from any.
    """

    def __init__(
        self,
        corners: CornerMap,
        resolution: float = 0.1,
        margin: float = 12.0,
        orientation_bins: int = 1,
        sigma_pos: float = 0.3,
        sigma_theta: float = 0.2,
    ) -> None:
        if len(corners) == 0:
            raise LocalizerError("the corner map is empty: the feature filter has nothing to match corners against")
        if resolution <= 0:
            raise LocalizerError(f"lookup grid resolution must be positive, got {resolution}")
        if orientation_bins < 1 or sigma_pos <= 0 or sigma_theta <= 0:
            raise LocalizerError(
                f"orientation_bins must be at least 1 and the sigmas positive, got {orientation_bins}, "
                f"{sigma_pos}, {sigma_theta}"
            )
        self.bins = orientation_bins
        self.xy = np.asarray(corners.xy, dtype=np.float64)
        self.theta = np.asarray(corners.theta, dtype=np.float64)
        self.resolution = resolution
        self.origin = self.xy.min(axis=0) - margin
        upper = self.xy.max(axis=0) + margin
        self.shape = tuple(np.ceil((upper - self.origin) / resolution).astype(int)[::-1])  # rows (y), cols (x)
        ys = self.origin[1] + (np.arange(self.shape[0]) + 0.5) * resolution
        xs = self.origin[0] + (np.arange(self.shape[1]) + 0.5) * resolution
        gx, gy = np.meshgrid(xs, ys)
        centres = np.column_stack([gx.ravel(), gy.ravel()])
        if orientation_bins == 1:
            _, index = cKDTree(self.xy).query(centres)
        else:
            k = min(CANDIDATES, len(self.xy))
            distance, near = cKDTree(self.xy).query(centres, k=k)
            distance, near = distance.reshape(len(centres), k), near.reshape(len(centres), k)
            headings = (np.arange(orientation_bins) + 0.5) * (2 * np.pi / orientation_bins)
            turn = np.asarray(wrap_angle(self.theta[near][:, :, None] - headings))  # (cells, k, bins)
            cost = (distance[:, :, None] / sigma_pos) ** 2 + (turn / sigma_theta) ** 2
            index = np.take_along_axis(near, cost.argmin(axis=1), axis=1).ravel()  # cell-major, then bin
        self.table = index.astype(np.int32).reshape(*self.shape, orientation_bins)
        # per cell (and bin), the chosen corner's x, y and theta: one gather each in the filter's hot loop
        # x + iy packed in one complex number: one gather gives both coordinates
        self.cell_xy = (self.xy[index, 0] + 1j * self.xy[index, 1]).astype(np.complex64)
        self.cell_theta = self.theta[index].astype(np.float32)

    def cells(self, x: np.ndarray, y: np.ndarray, theta: np.ndarray | None = None) -> np.ndarray:
        """Flat index (into ``cell_xy``, ``cell_theta``) of points ``x``, ``y`` seen with map heading ``theta``
        (float32 for speed; ``theta`` is needed when there is more than one orientation bin).

        Points inside the grid get their cell. Points outside get some valid cell, not always the nearest
        edge one; the filter measures the true distance to that cell's corner, so such a point (more than
        ``margin`` from every corner) only ever scores low, as it should.
        """
        # The filter's hot spot: a float np.mod took 5x the time of the rest of this function, so the heading
        # bin wraps in integers (a mask for 2^k bins).
        inv = np.float32(1.0 / self.resolution)
        flat = np.floor((y - np.float32(self.origin[1])) * inv)
        flat *= np.float32(self.shape[1])
        flat += np.floor((x - np.float32(self.origin[0])) * inv)
        np.clip(flat, 0, self.shape[0] * self.shape[1] - 1, out=flat)
        cell = flat.astype(np.int32)
        if self.bins == 1:
            return cell
        if theta is None:
            raise LocalizerError("this lookup has orientation bins: cells() needs the headings too")
        cell *= self.bins
        turns = np.asarray(theta, dtype=np.float32) * np.float32(self.bins / (2 * np.pi))
        heading = np.floor(turns).astype(np.int32)
        if self.bins & (self.bins - 1) == 0:
            heading &= self.bins - 1  # two's complement: the floor modulo for negative turns too
        else:
            np.remainder(heading, self.bins, out=heading)
        cell += heading
        return cell

    def nearest(self, x: np.ndarray, y: np.ndarray, theta: np.ndarray | None = None) -> np.ndarray:
        """Index of the chosen corner for points ``x``, ``y`` (headings ``theta``) of any equal shape."""
        return self.table.ravel()[self.cells(x, y, theta)]
