"""What an imported mesh world is made of, and the checks that catch what would hurt localization.

An import is refused when a wall, ceiling or piece of clutter is longer than ``MAX_OBJECT_M`` (a mesh read in
the wrong unit). It leaves out, with a warning naming them, objects that lie wholly outside the building
(``FAR_OUTSIDE_M`` beyond the walls' extent, or far below the floor or above the ceiling), and it warns when the
world has no walls, no ceiling, or a floor-named object that stands like a wall.
"""

from __future__ import annotations

import warnings
from collections import Counter
from pathlib import Path

import numpy as np

from pimm_env.errors import MapFileError
from pimm_env.world.model import World
from pimm_env.world.semantics import SemanticClass
from pimm_env.world.shapes import Mesh

MAX_OBJECT_M = 100.0  # no wall, ceiling or furniture of a building is longer
FAR_OUTSIDE_M = 10.0  # beyond the walls' (or floors') extent by this much: not part of the building
MAX_ABOVE_FLOOR_M = 30.0


def floor_height(world: World) -> float:
    """The walkable height: the largest upward-facing horizontal surface of the floor objects (a floor
    part's rim or a raised step does not lift the whole floor)."""
    area_by_z: dict[float, float] = {}
    tops = []
    for element in world.elements:
        if element.semantic != SemanticClass.FLOOR:
            continue
        tops.append(element.shape.z_range[1])
        if not isinstance(element.shape, Mesh):
            continue
        tri = element.shape.vertices[element.shape.triangles]
        normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        area = 0.5 * np.linalg.norm(normal, axis=1)
        up = (normal[:, 2] > 0.99 * 2 * area) & (area > 0)
        for z, a in zip(np.round(tri[up, :, 2].mean(axis=1), 2), area[up], strict=True):
            area_by_z[float(z)] = area_by_z.get(float(z), 0.0) + float(a)
    if area_by_z:
        return max(area_by_z, key=lambda z: area_by_z[z])
    if not tops:
        raise MapFileError(f"{world.source}: no floor object")
    return max(tops)


def _bounds(element) -> tuple[np.ndarray, np.ndarray]:
    shape = element.shape
    if isinstance(shape, Mesh):
        return shape.vertices.min(axis=0), shape.vertices.max(axis=0)
    xy = shape.corners_xy() if hasattr(shape, "corners_xy") else np.array([shape.center[:2]])
    z0, z1 = shape.z_range
    return np.array([*xy.min(axis=0), z0]), np.array([*xy.max(axis=0), z1])


def check_mesh_world(world: World, floor_z: float, mesh_path: Path, ceiling_added: bool) -> list[str]:
    """Refuse absurd scales, warn about what will hurt localization; returns the names of objects to leave out."""
    bounds = {e.name: _bounds(e) for e in world.elements}
    for element in world.elements:
        lo, hi = bounds[element.name]
        length = float(np.max(hi[:2] - lo[:2]))
        if element.semantic != SemanticClass.FLOOR and length > MAX_OBJECT_M:
            raise MapFileError(
                f"{mesh_path}: object {element.name!r} ({element.semantic.name.lower()}) is {length:.0f} m long: "
                "is the mesh in another unit (centimetres, millimetres)? Scale it to metres"
            )
    structure = [e for e in world.elements if e.semantic == SemanticClass.WALL] or [
        e for e in world.elements if e.semantic == SemanticClass.FLOOR
    ]
    lo = np.min([bounds[e.name][0] for e in structure], axis=0) - FAR_OUTSIDE_M
    hi = np.max([bounds[e.name][1] for e in structure], axis=0) + FAR_OUTSIDE_M
    lo[2], hi[2] = floor_z - FAR_OUTSIDE_M, floor_z + MAX_ABOVE_FLOOR_M
    left_out = [e.name for e in world.elements if np.any(bounds[e.name][0] > hi) or np.any(bounds[e.name][1] < lo)]
    if left_out:
        warnings.warn(
            f"{mesh_path}: left out {len(left_out)} object(s) lying outside the building: {', '.join(left_out)}",
            stacklevel=2,
        )
    classes = Counter(e.semantic for e in world.elements if e.name not in left_out)
    if not classes[SemanticClass.WALL]:
        warnings.warn(f"{mesh_path}: no object is a wall: PIMM and AMCL need walls (give --rules)", stacklevel=2)
    if not classes[SemanticClass.CEILING] and not ceiling_added:
        warnings.warn(
            f"{mesh_path}: the world has no ceiling: PIMM finds corners under ceilings (give --ceiling-height H)",
            stacklevel=2,
        )
    for element in world.elements:
        lo_e, hi_e = bounds[element.name]
        size = hi_e - lo_e
        if element.semantic == SemanticClass.FLOOR and size[2] > 1.0 and size[2] > 4 * min(size[0], size[1]):
            warnings.warn(
                f"{mesh_path}: object {element.name!r} is classed floor but stands {size[2]:.1f} m tall and "
                f"{min(size[0], size[1]):.2f} m thin, like a wall: check the name rules (--rules)",
                stacklevel=2,
            )
    return left_out


def describe_world(world: World) -> str:
    """One paragraph of what a world is made of: objects per class, floor area, ceiling heights."""
    counts = Counter(e.semantic.name.lower() for e in world.elements)
    floor_xy = [_bounds(e) for e in world.elements if e.semantic == SemanticClass.FLOOR]
    area = ""
    if floor_xy:
        lo = np.min([b[0] for b in floor_xy], axis=0)
        hi = np.max([b[1] for b in floor_xy], axis=0)
        area = f"; floor {hi[0] - lo[0]:.1f} x {hi[1] - lo[1]:.1f} m"
    from pimm_env.mapping.ceilings import ceiling_levels

    heights = [round(h - world.floor_z, 2) for h in ceiling_levels(world)]
    parts = ", ".join(f"{n} {c}" for c, n in sorted(counts.items()))
    ceilings = f"ceilings at {heights} m above the floor" if heights else "no ceiling"
    return f"{world.name}: {len(world.elements)} objects ({parts}){area}; {ceilings}"
