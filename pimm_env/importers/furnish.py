"""Mapped furniture for a bare floor plan: desks, cabinets and columns at seeded random free places."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from pimm_env.importers.vectorize import FloorPlan


@dataclass(frozen=True)
class Piece:
    kind: str
    size: tuple[float, float, float]  # x, y, z extent (m); a column's x is its diameter


#: Typical office sizes (m). Columns reach the ceiling.
PIECES = (Piece("desk", (1.4, 0.7, 0.75)), Piece("cabinet", (0.9, 0.45, 1.9)), Piece("column", (0.4, 0.4, 0.0)))
PASSAGE = 0.7  # free space kept around every piece (m), so that furniture never closes a corridor or a door


def furnish(plan: FloorPlan, count: int, seed: int, ceiling: float, tries: int = 200) -> list[dict[str, Any]]:
    """``count`` clutter elements (world-file mappings) placed uniformly in free space, each at least
    ``PASSAGE`` from walls and from each other; fewer if the plan has no room left."""
    import shapely
    from shapely.affinity import rotate, translate
    from shapely.geometry import Point, box

    rng = np.random.default_rng(seed)
    room = shapely.unary_union(plan.spaces)
    x0, y0, x1, y1 = room.bounds
    elements: list[dict[str, Any]] = []
    for index in range(count):
        piece = PIECES[int(rng.integers(len(PIECES)))]
        for _ in range(tries):
            x, y, yaw = rng.uniform(x0, x1), rng.uniform(y0, y1), rng.uniform(0, np.pi)
            if piece.kind == "column":
                footprint = Point(x, y).buffer(piece.size[0] / 2)
            else:
                shape = box(-piece.size[0] / 2, -piece.size[1] / 2, piece.size[0] / 2, piece.size[1] / 2)
                footprint = translate(rotate(shape, yaw, use_radians=True), x, y)
            if room.contains(footprint.buffer(PASSAGE)):
                break
        else:
            return elements
        room = room.difference(footprint.buffer(PASSAGE))
        name = f"{piece.kind}_{index + 1}"
        if piece.kind == "column":
            shape_spec: dict[str, Any] = {
                "cylinder": {"center": [round(x, 4), round(y, 4)], "radius": piece.size[0] / 2, "z": [0.0, ceiling]}
            }
        else:
            shape_spec = {
                "box": {
                    "center": [round(x, 4), round(y, 4), piece.size[2] / 2],
                    "size": list(piece.size),
                    "yaw": round(float(yaw), 4),
                }
            }
        elements.append({"name": name, "class": "clutter", **shape_spec})
    return elements
