"""A generated building's plan: free-space rectangles (rooms, corridors, halls) and the doors between them,
drawn by ``training/buildings.py`` and ``training/furnished.py`` and turned into a world there."""

from __future__ import annotations

from dataclasses import dataclass, field

#: An axis-aligned rectangle (x0, y0, x1, y1), m.
Box = tuple[float, float, float, float]
#: Door width in the look-alike and furnished families (m): wide enough for the route planner's 0.5 m
#: clearance, so routes go into the rooms rather than only up and down one corridor.
DOOR = 1.3
#: The raster a plan is drawn on (m).
RES = 0.05


@dataclass(frozen=True)
class Room:
    """A free rectangle (x0, y0, x1, y1) with its ceiling height and kind."""

    box: Box
    ceiling: float
    kind: str  # corridor | office | hall; furnished: living | bedroom | kitchen | bath | shop | store | ward | station


@dataclass
class Plan:
    rooms: list[Room]
    doors: list[Box]
    wall: float  # wall thickness (m)
    pillars: list[tuple[float, float]] = field(default_factory=list)  # 0.4 m square, floor to ceiling
