"""Solid shapes that make up a world: boxes, vertical cylinders, vertical prisms over a polygon, and
triangle meshes.

Every shape answers the two questions the rest of the project asks of geometry: its vertical extent,
and which cells of a horizontal grid it covers at a given height (its footprint, used for the occupancy
grid, the corner map and collision checks).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pimm_env.world.grid import GridSpec, points_in_ring


@dataclass(frozen=True)
class Box:
    """A box with vertical sides, rotated by ``yaw`` about its vertical axis."""

    center: tuple[float, float, float]
    half_extents: tuple[float, float, float]
    yaw: float = 0.0

    @property
    def z_range(self) -> tuple[float, float]:
        return (self.center[2] - self.half_extents[2], self.center[2] + self.half_extents[2])

    def corners_xy(self) -> np.ndarray:
        """The four footprint corners, counter-clockwise, shape (4, 2)."""
        hx, hy = self.half_extents[0], self.half_extents[1]
        local = np.array([[-hx, -hy], [hx, -hy], [hx, hy], [-hx, hy]])
        c, s = np.cos(self.yaw), np.sin(self.yaw)
        return local @ np.array([[c, s], [-s, c]]) + np.asarray(self.center[:2])

    def footprint(self, grid: GridSpec, z: float) -> np.ndarray:
        mask = grid.empty_mask()
        z0, z1 = self.z_range
        if not z0 <= z <= z1:
            return mask
        window = grid.window(self.corners_xy(), pad=grid.resolution)
        if window is None:
            return mask
        rows, cols, xs, ys = window
        c, s = np.cos(self.yaw), np.sin(self.yaw)
        dx, dy = xs - self.center[0], ys - self.center[1]
        # Just under half a cell of slack: thin panels (glass, 1 cm) still mark the cells they cross, while
        # a cell whose centre lies exactly on a face stays free.
        slack = 0.49 * grid.resolution
        inside = (np.abs(c * dx + s * dy) <= self.half_extents[0] + slack) & (
            np.abs(-s * dx + c * dy) <= self.half_extents[1] + slack
        )
        mask[rows, cols] = inside
        return mask


@dataclass(frozen=True)
class Cylinder:
    """A vertical cylinder (round posts, pillars)."""

    center: tuple[float, float]
    radius: float
    z_range: tuple[float, float]

    def footprint(self, grid: GridSpec, z: float) -> np.ndarray:
        mask = grid.empty_mask()
        if not self.z_range[0] <= z <= self.z_range[1]:
            return mask
        r = self.radius
        cx, cy = self.center
        window = grid.window(np.array([[cx - r, cy - r], [cx + r, cy + r]]), pad=grid.resolution)
        if window is None:
            return mask
        rows, cols, xs, ys = window
        mask[rows, cols] = np.hypot(xs - cx, ys - cy) <= r + 0.49 * grid.resolution
        return mask


def segment_points(segments: np.ndarray, step: float) -> np.ndarray:
    """Points at most ``step`` apart along each of the (S, 2, 2) ``segments``, both ends included, shape (N, 2)."""
    if len(segments) == 0:
        return np.zeros((0, 2))
    direction = segments[:, 1] - segments[:, 0]
    steps = np.maximum(1, np.ceil(np.linalg.norm(direction, axis=1) / step).astype(int))
    t = np.concatenate([np.linspace(0.0, 1.0, n + 1) for n in steps])
    index = np.repeat(np.arange(len(segments)), steps + 1)
    return segments[index, 0] + t[:, None] * direction[index]


@dataclass(frozen=True)
class Mesh:
    """A triangle mesh in map coordinates: ``vertices`` (V, 3) and ``triangles`` (T, 3) indices."""

    vertices: np.ndarray
    triangles: np.ndarray

    @property
    def z_range(self) -> tuple[float, float]:
        return (float(self.vertices[:, 2].min()), float(self.vertices[:, 2].max()))

    def section(self, z: float) -> np.ndarray:
        """Segments where the plane at height ``z`` cuts the mesh, shape (S, 2, 2)."""
        tri = self.vertices[self.triangles]
        d = tri[:, :, 2] - z
        segments = []
        for i, j in ((0, 1), (1, 2), (2, 0)):
            crosses = (d[:, i] < 0) != (d[:, j] < 0)
            t = np.where(crosses, d[:, i] / np.where(crosses, d[:, i] - d[:, j], 1.0), 0.0)
            point = tri[:, i, :2] + t[:, None] * (tri[:, j, :2] - tri[:, i, :2])
            segments.append((crosses, point))
        (c0, p0), (c1, p1), (c2, p2) = segments
        ends = []
        for ca, pa, cb, pb in ((c0, p0, c1, p1), (c1, p1, c2, p2), (c0, p0, c2, p2)):
            both = ca & cb
            ends.append(np.stack([pa[both], pb[both]], axis=1))
        return np.concatenate(ends, axis=0) if ends else np.zeros((0, 2, 2))

    def footprint(self, grid: GridSpec, z: float) -> np.ndarray:
        mask = grid.empty_mask()
        segments = self.section(z)
        if len(segments) == 0:
            return mask
        rows, cols, valid = grid.cells_of(segment_points(segments, grid.resolution / 2))
        mask[rows[valid], cols[valid]] = True
        return mask


@dataclass(frozen=True)
class Prism:
    """A vertical prism over a polygon with holes: the walls of a floor plan as one solid piece.

    ``outline`` (K, 2) and each hole (K_i, 2) are rings of (x, y) vertices, not repeated at the end.
    """

    outline: np.ndarray
    holes: tuple[np.ndarray, ...]
    z_range: tuple[float, float]

    def rings(self) -> list[np.ndarray]:
        return [self.outline, *self.holes]

    def corners_xy(self) -> np.ndarray:
        return self.outline

    def footprint(self, grid: GridSpec, z: float) -> np.ndarray:
        """Cells whose centre lies inside the outline and outside every hole (even-odd over all rings)."""
        mask = grid.empty_mask()
        if not self.z_range[0] <= z <= self.z_range[1]:
            return mask
        window = grid.window(self.outline, pad=grid.resolution)
        if window is None:
            return mask
        rows, cols, xs, ys = window
        inside = np.zeros(xs.shape, dtype=bool)
        for ring in self.rings():
            inside ^= points_in_ring(xs, ys, ring)
        mask[rows, cols] = inside
        return mask


Shape = Box | Cylinder | Prism | Mesh
