"""The world model: a building as named solid elements with a semantic class, plus named area polygons."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from pimm_env.world.grid import GridSpec
from pimm_env.world.semantics import SemanticClass
from pimm_env.world.shapes import Box, Cylinder, Prism, Shape


@dataclass(frozen=True)
class Element:
    """One solid piece of the world."""

    name: str
    semantic: SemanticClass
    shape: Shape
    occupancy: bool


@dataclass
class World:
    """A building: its elements, its named areas and the height of its floor; a world made from a scan also
    knows where the scan saw its walls (``seen_walls``, (S, 2) points in the plane)."""

    name: str
    elements: list[Element]
    areas: dict[str, np.ndarray]
    floor_z: float = 0.0
    source: Path | None = None
    seen_walls: np.ndarray | None = None
    _footprints: dict[tuple[Any, ...], np.ndarray] = field(default_factory=dict, repr=False)

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Lower and upper (x, y) corners of everything in the world."""
        points = [poly for poly in self.areas.values()]
        for element in self.elements:
            shape = element.shape
            if isinstance(shape, Box):
                points.append(shape.corners_xy())
            elif isinstance(shape, Cylinder):
                c = np.asarray(shape.center)
                points.append(np.stack([c - shape.radius, c + shape.radius]))
            elif isinstance(shape, Prism):
                points.append(shape.outline)
            else:
                points.append(shape.vertices[:, :2])
        stacked = np.concatenate(points, axis=0)
        return stacked.min(axis=0), stacked.max(axis=0)

    def grid(self, resolution: float) -> GridSpec:
        lower, upper = self.bounds()
        return GridSpec.covering(lower, upper, resolution)

    def footprint(
        self,
        grid: GridSpec,
        z: float,
        classes: Sequence[SemanticClass] | None = None,
        occupancy_only: bool = False,
    ) -> np.ndarray:
        """Cells covered at height ``z`` by elements of ``classes`` (all if None)."""
        key = (grid, round(z, 4), tuple(classes) if classes else None, occupancy_only)
        if key not in self._footprints:
            mask = grid.empty_mask()
            for element in self.elements:
                if classes is not None and element.semantic not in classes:
                    continue
                if occupancy_only and not element.occupancy:
                    continue
                mask |= element.shape.footprint(grid, z)
            self._footprints[key] = mask
        return self._footprints[key]

    def area_mask(self, grid: GridSpec) -> np.ndarray:
        """Cells inside any named area."""
        mask = grid.empty_mask()
        for polygon in self.areas.values():
            mask |= grid.points_in_polygon(polygon)
        return mask

    def area_of(self, x: float, y: float) -> str | None:
        """Name of the area holding the point, or None. (The env asks at every step: an imported plan has tens
        of areas of a hundred vertices, so each is first ruled out by its box.)"""
        for name, polygon in self.areas.items():
            lo, hi = polygon.min(axis=0), polygon.max(axis=0)
            if lo[0] <= x <= hi[0] and lo[1] <= y <= hi[1] and point_in_polygon(x, y, polygon):
                return name
        return None

    def ceiling_heights(self) -> list[float]:
        """Distinct heights of the undersides of ceiling elements, lowest first."""
        heights = {round(e.shape.z_range[0], 3) for e in self.elements if e.semantic == SemanticClass.CEILING}
        return sorted(heights)


def point_in_polygon(x: float, y: float, polygon: np.ndarray) -> bool:
    """Whether (x, y) lies inside ``polygon`` (N, 2) by the even-odd rule: a ray towards +x crosses its edges
    an odd number of times."""
    a = np.asarray(polygon, dtype=float)
    b = np.roll(a, -1, axis=0)
    crosses = (a[:, 1] > y) != (b[:, 1] > y)
    a, b = a[crosses], b[crosses]
    at = a[:, 0] + (y - a[:, 1]) * (b[:, 0] - a[:, 0]) / (b[:, 1] - a[:, 1])
    return bool(np.count_nonzero(x < at) % 2)
