"""Where a world's ceilings are: the heights of their undersides and the cells each height covers.

Boxes and prisms are solid: their underside is the bottom of their vertical extent and they cover their
footprint. A mesh ceiling can be anything a modeller drew: a closed slab, a single plane (facing up or down), a
ceiling at several heights, sloped parts. Its heights are read from its horizontal faces (the undersides: the
faces that look down, or a one-sided plane's only face) and from the lowest points of its sloped faces, each
height kept where it spans at least ``min_area`` square metres; the cells under a height are those its horizontal
and sloped faces cover from above, so a slab covers its whole area, not only the rim its cross-section would give.
A corner under several heights (a sloped part spans many) is one corner, at the lowest (corner_map.py).
"""

from __future__ import annotations

import numpy as np

from pimm_env.world.grid import GridSpec
from pimm_env.world.model import World
from pimm_env.world.semantics import SemanticClass
from pimm_env.world.shapes import Mesh

LEVEL_STEP = 0.05  # heights closer than this are one ceiling height (m)
MIN_AREA = 1.0  # a ceiling height counts where its faces span at least this much (m^2)
FLAT_NZ = 0.95  # a face is horizontal when its normal's z part is at least this
VERTICAL_NZ = 0.2  # a face is vertical (a wall of the ceiling, not a cover) below this


def _faces(mesh: Mesh) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Triangles (T, 3, 3), their unit normals' z and their areas."""
    tri = mesh.vertices[mesh.triangles]
    normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    norm = np.linalg.norm(normal, axis=1)
    nz = np.divide(normal[:, 2], norm, out=np.zeros(len(tri)), where=norm > 0)
    return tri, nz, 0.5 * norm


def ceiling_levels(world: World, min_area: float = MIN_AREA) -> list[float]:
    """The heights of the ceilings' undersides, lowest first (see the module docstring)."""
    area: dict[float, float] = {}
    solid: set[float] = set()
    for element in world.elements:
        if element.semantic != SemanticClass.CEILING:
            continue
        if not isinstance(element.shape, Mesh):
            solid.add(round(element.shape.z_range[0], 3))
            continue
        tri, nz, tri_area = _faces(element.shape)
        down = nz <= -FLAT_NZ
        faces = down if down.any() else nz >= FLAT_NZ
        # a sloped part counts from its lowest point, where the walls under it first meet it
        sloped = (np.abs(nz) >= VERTICAL_NZ) & (np.abs(nz) < FLAT_NZ)
        heights = np.concatenate([tri[faces, :, 2].mean(axis=1), tri[sloped, :, 2].min(axis=1)])
        for z, a in zip(heights, np.concatenate([tri_area[faces], tri_area[sloped]]), strict=True):
            key = round(round(float(z) / LEVEL_STEP) * LEVEL_STEP, 3)
            area[key] = area.get(key, 0.0) + float(a)
    mesh_levels = [z for z, a in area.items() if a >= min_area]
    return sorted(solid | set(mesh_levels))


def ceiling_cover(world: World, grid: GridSpec, level: float) -> np.ndarray:
    """Cells under the ceiling at height ``level``."""
    mask = grid.empty_mask()
    for element in world.elements:
        if element.semantic != SemanticClass.CEILING:
            continue
        if not isinstance(element.shape, Mesh):
            mask |= element.shape.footprint(grid, level + 0.01)
            continue
        tri, nz, _ = _faces(element.shape)
        z0, z1 = tri[:, :, 2].min(axis=1), tri[:, :, 2].max(axis=1)
        near = (np.abs(nz) >= VERTICAL_NZ) & (z0 <= level + LEVEL_STEP) & (z1 >= level - LEVEL_STEP)
        for triangle in tri[near, :, :2]:
            _fill_triangle(mask, grid, triangle)
    return mask


def _fill_triangle(mask: np.ndarray, grid: GridSpec, triangle: np.ndarray) -> None:
    """Mark the cells whose centre lies in a triangle (2D, (3, 2)), or that hold one of its vertices."""
    window = grid.window(triangle, pad=grid.resolution)
    if window is None:
        return
    rows, cols, xs, ys = window
    a, b, c = triangle
    d = (b[1] - c[1]) * (a[0] - c[0]) + (c[0] - b[0]) * (a[1] - c[1])
    if abs(d) < 1e-12:
        return
    l1 = ((b[1] - c[1]) * (xs - c[0]) + (c[0] - b[0]) * (ys - c[1])) / d
    l2 = ((c[1] - a[1]) * (xs - c[0]) + (a[0] - c[0]) * (ys - c[1])) / d
    eps = 1e-9
    inside = (l1 >= -eps) & (l2 >= -eps) & (1 - l1 - l2 >= -eps)
    mask[rows, cols] |= inside
    r, k, valid = grid.cells_of(triangle)
    mask[r[valid], k[valid]] = True
