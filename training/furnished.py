"""The furnished families of generated buildings: homes, shops and hospital wards, their rooms furnished by kind
against the walls (beds, wardrobes, sofas, shelves, kitchen units, lockers, shelving) with every doorway left
free, and a ward's nurses' station behind a glass partition (class wall, as the iilab's glass); for the lintel
seeds, lintels over the doorways. Drawn by ``training/buildings.py`` for the furnished seeds only."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from training.plans import DOOR, Box, Plan, Room

#: Sides of a room: the wall at y1 ("north"), y0, x1, x0.
SIDES = ("north", "south", "east", "west")
#: A piece of furniture along a wall: name, length along the wall, depth into the room, height (m), chance.
Unit = tuple[str, float, float, float, float]
#: What the rooms of a home are.
ROOM_KINDS = ("living", "bedroom", "kitchen", "bath")
#: The rooms that are furnished (a ward's station gets its desk and glass separately).
FURNISHED_KINDS = ("living", "bedroom", "kitchen", "bath", "shop", "store", "ward")


def draw_home(rng: np.random.Generator, plan: Plan, ceiling: float) -> None:
    """A hallway along x with rooms of several sizes on both sides, each a living room, bedroom, kitchen or
    bathroom (``Room.kind``), a door from the hallway into each."""
    t, width, length = plan.wall, float(rng.uniform(1.2, 1.6)), float(rng.uniform(9.0, 15.0))
    plan.rooms.append(Room((0.0, 0.0, length, width), ceiling, "corridor"))
    for side in (1, -1):
        x = 0.0
        while True:
            w, d = float(rng.uniform(2.8, 5.0)), float(rng.uniform(3.0, 4.6))
            if x + w > length:
                break
            y = (width + t, width + t + d) if side > 0 else (-t - d, -t)
            kind = ROOM_KINDS[int(rng.integers(len(ROOM_KINDS)))]
            plan.rooms.append(Room((x, y[0], x + w, y[1]), ceiling, kind))
            door_x = x + float(rng.uniform(0.2, w - DOOR - 0.2))
            wall = (width, width + t) if side > 0 else (-t, 0.0)
            plan.doors.append((door_x, wall[0], door_x + DOOR, wall[1]))
            x += w + t


def draw_shop(rng: np.random.Generator, plan: Plan, ceiling: float) -> None:
    """A sales floor (8-14 x 10-20 m, 3-4.5 m high) with a store room behind it along its back wall."""
    t = plan.wall
    w, d = float(rng.uniform(10.0, 20.0)), float(rng.uniform(8.0, 14.0))
    high = float(rng.uniform(3.0, 4.5))
    plan.rooms.append(Room((0.0, 0.0, w, d), high, "shop"))
    store_w = float(rng.uniform(4.0, min(8.0, w - 2.0)))
    store_x = float(rng.uniform(0.0, w - store_w))
    plan.rooms.append(Room((store_x, d + t, store_x + store_w, d + t + float(rng.uniform(3.0, 5.0))), ceiling, "store"))
    door_x = store_x + float(rng.uniform(0.2, store_w - DOOR - 0.2))
    plan.doors.append((door_x, d, door_x + DOOR, d + t))


def draw_ward(rng: np.random.Generator, plan: Plan, ceiling: float) -> None:
    """A corridor (2.2-2.8 m wide) with rows of patient rooms on both sides, alike as a ward's are, and a
    nurses' station: a bay off the corridor behind a glass partition."""
    t, width = plan.wall, float(rng.uniform(2.2, 2.8))
    room_w, room_d, count = float(rng.uniform(3.6, 4.8)), float(rng.uniform(4.5, 6.0)), int(rng.integers(4, 8))
    door_at = float(rng.uniform(0.2, room_w - DOOR - 0.2))
    length = count * (room_w + t) - t
    station = float(rng.uniform(3.0, 4.5))
    plan.rooms.append(Room((0.0, 0.0, length + t + station, width), ceiling, "corridor"))
    for side in (1, -1):
        for k in range(count):
            a = k * (room_w + t)
            y = (width + t, width + t + room_d) if side > 0 else (-t - room_d, -t)
            plan.rooms.append(Room((a, y[0], a + room_w, y[1]), ceiling, "ward"))
            wall = (width, width + t) if side > 0 else (-t, 0.0)
            plan.doors.append((a + door_at, wall[0], a + door_at + DOOR, wall[1]))
    # the station opens onto the corridor over its whole width; the glass partition stands in that opening
    plan.rooms.append(Room((length + t, width + t, length + t + station, width + t + 3.0), ceiling, "station"))
    plan.doors.append((length + t, width, length + t + station, width + t))


def _against(
    name: str, room: Box, side: str, at: float, length: float, depth: float, height: float, z0: float = 0.0
) -> dict[str, Any]:
    """A box of furniture standing against the inner face of ``room``'s wall on ``side``, ``at`` metres along
    that wall from its start (x0 or y0), ``length`` along it, ``depth`` into the room (class clutter)."""
    x0, y0, x1, y1 = room
    if side in ("north", "south"):
        y = (y1 - depth, y1) if side == "north" else (y0, y0 + depth)
        low, high = [x0 + at, y[0], z0], [x0 + at + length, y[1], z0 + height]
    else:
        x = (x1 - depth, x1) if side == "east" else (x0, x0 + depth)
        low, high = [x[0], y0 + at, z0], [x[1], y0 + at + length, z0 + height]
    return _box(name, low, high)


def _box(name: str, low: Sequence[float], high: Sequence[float], semantic: str = "clutter") -> dict[str, Any]:
    """A box element from its lowest to its highest corner (m), of class ``semantic``."""
    return {
        "name": name,
        "class": semantic,
        "box": {"min": [round(v, 3) for v in low], "max": [round(v, 3) for v in high]},
    }


def _blocks_a_door(element: dict[str, Any], doors: list[Box], approach: float) -> bool:
    """Whether a box element stands in a doorway or within ``approach`` of it on either side of its wall."""
    (x0, y0, _), (x1, y1, _) = element["box"]["min"], element["box"]["max"]
    for dx0, dy0, dx1, dy1 in doors:
        across_x = dx1 - dx0 < dy1 - dy0  # the door's thin side is its wall's thickness: the wall runs along y
        grow_x, grow_y = (approach, 0.0) if across_x else (0.0, approach)
        if x0 < dx1 + grow_x and dx0 - grow_x < x1 and y0 < dy1 + grow_y and dy0 - grow_y < y1:
            return True
    return False


def _free_runs(room: Box, side: str, doors: list[Box], clearance: float) -> list[tuple[float, float]]:
    """Stretches (from, to: metres along the wall on ``side``) that no door of ``room`` comes within
    ``clearance`` of: where furniture may stand against that wall and leave the doorway free."""
    x0, y0, x1, y1 = room
    horizontal = side in ("north", "south")
    start, end = (x0, x1) if horizontal else (y0, y1)
    at = {"north": y1, "south": y0, "east": x1, "west": x0}[side]
    blocked = []
    for dx0, dy0, dx1, dy1 in doors:
        touches = (dy0 - 1e-6 <= at <= dy1 + 1e-6) if horizontal else (dx0 - 1e-6 <= at <= dx1 + 1e-6)
        if touches:
            lo, hi = (dx0, dx1) if horizontal else (dy0, dy1)
            if hi > start and lo < end:
                blocked.append((lo - clearance, hi + clearance))
    runs, cursor = [], start
    for lo, hi in sorted(blocked):
        if lo > cursor:
            runs.append((cursor - start, lo - start))
        cursor = max(cursor, hi)
    if cursor < end:
        runs.append((cursor - start, end - start))
    return [(a, b) for a, b in runs if b - a >= 0.5]


def furnish(plan: Plan, rng: np.random.Generator) -> list[dict[str, Any]]:
    """Furniture against the walls of every room of a furnished building, by the room's kind (the beds,
    wardrobes, sofas, shelves, kitchen units, counters and shelving a home, a shop or a ward holds), never in
    front of a door; and the glass partition of a ward's nurses' station (class wall, as the iilab's glass)."""
    elements: list[dict[str, Any]] = []
    for k, room in enumerate(plan.rooms):
        if room.kind not in FURNISHED_KINDS:
            continue
        for side in SIDES:
            for j, (lo, hi) in enumerate(_free_runs(room.box, side, plan.doors, 0.8)):
                placed = _pieces(f"{room.kind}_{k}_{side}_{j}", room, side, lo, hi, rng)
                elements += [e for e in placed if not _blocks_a_door(e, plan.doors, 0.8)]
    for k, room in enumerate(r for r in plan.rooms if r.kind == "shop"):
        elements += _gondolas(f"shop_{k}", room, rng)
    for k, room in enumerate(r for r in plan.rooms if r.kind == "station"):
        x0, _, x1, _ = room.box
        y = room.box[1] - plan.wall / 2
        opening = float(rng.uniform(0.9, 1.3))  # the way in, at the corridor's far end
        elements.append(_box(f"glass_{k}", (x0, y - 0.01, 0.0), (x1 - opening, y + 0.01, room.ceiling), "wall"))
        elements.append(_against(f"station_desk_{k}", room.box, "north", 0.3, x1 - x0 - 0.6, 0.8, 1.05))
    return elements


def _gondolas(name: str, room: Room, rng: np.random.Generator) -> list[dict[str, Any]]:
    """Free-standing shelf rows (1.0 m deep, 1.4-1.8 m high) across a sales floor, aisles of 1.8-2.4 m between
    them and 2 m clear of its walls, and a checkout counter by its front wall."""
    x0, y0, x1, y1 = room.box
    height, aisle = float(rng.uniform(1.4, 1.8)), float(rng.uniform(1.8, 2.4))
    out: list[dict[str, Any]] = []
    x = x0 + 2.0
    while x + 1.0 <= x1 - 2.0:
        out.append(_box(f"{name}_gondola_{len(out)}", (x, y0 + 2.5, 0.0), (x + 1.0, y1 - 2.0, height)))
        x += 1.0 + aisle
    counter_x = float(rng.uniform(x0 + 0.5, x1 - 3.0))
    out.append(_box(f"{name}_counter", (counter_x, y0 + 1.0, 0.0), (counter_x + 2.5, y0 + 1.7, 1.0)))
    return out


def _along(
    name: str,
    room: Room,
    side: str,
    lo: float,
    hi: float,
    rng: np.random.Generator,
    units: tuple[Unit, ...],
    z0: float = 0.0,
) -> list[dict[str, Any]]:
    """Units (name, length, depth, height, chance) placed one after another along a free run of a wall, each
    with its chance, with gaps of 0-0.6 m."""  # fmt: skip
    out, at = [], lo + float(rng.uniform(0.0, 0.3))
    for unit, length, depth, height, chance in units:
        if at + length > hi:
            break
        if rng.random() < chance:
            out.append(_against(f"{name}_{unit}", room.box, side, at, length, depth, height, z0))
            at += length + float(rng.uniform(0.0, 0.6))
    return out


def _units(kind: str, rng: np.random.Generator) -> tuple[Unit, ...]:
    """What a room of ``kind`` stands along one free stretch of wall, in order: (name, length along the wall,
    depth into the room, height, chance), sizes drawn where they vary."""
    if kind == "living":
        shelf = float(rng.uniform(0.8, 2.0))
        return (("sofa", 2.0, 0.9, 0.85, 0.5), ("shelf", shelf, 0.35, 2.0, 0.6), ("tv_unit", 1.5, 0.45, 0.5, 0.4))
    if kind == "bedroom":
        bed, wardrobe = float(rng.uniform(1.4, 1.8)), float(rng.uniform(1.2, 2.0))
        return (("bedside", 0.45, 0.4, 0.55, 0.5), ("bed", bed, 2.0, 0.55, 0.4), ("wardrobe", wardrobe, 0.6, 2.1, 0.6))
    if kind == "bath":
        return (("tub", 1.7, 0.75, 0.55, 0.4), ("basin", 0.6, 0.45, 0.85, 0.6))
    if kind in ("shop", "store"):
        height = float(rng.uniform(1.8, 2.4))
        return tuple((f"shelving_{i}", float(rng.uniform(1.0, 2.5)), 0.5, height, 0.85) for i in range(12))
    if kind == "ward":
        return (("locker", 0.5, 0.5, 0.9, 0.7), ("bed", 1.0, 2.1, 0.6, 0.6), ("wardrobe", 0.9, 0.6, 2.0, 0.4))
    raise ValueError(f"no furniture for a room of kind {kind!r}")


def _pieces(name: str, room: Room, side: str, lo: float, hi: float, rng: np.random.Generator) -> list[dict[str, Any]]:
    """The furniture of one free stretch (``lo``-``hi`` m along the wall on ``side``) of ``room``."""
    if room.kind == "kitchen":
        return _kitchen(name, room, side, lo, hi, rng)
    return _along(name, room, side, lo, hi, rng, _units(room.kind, rng))


def _kitchen(name: str, room: Room, side: str, lo: float, hi: float, rng: np.random.Generator) -> list[dict[str, Any]]:
    length = min(hi - lo - 0.1, float(rng.uniform(1.8, 3.6)))
    if rng.random() < 0.5 or length < 0.6:
        return _along(name, room, side, lo, hi, rng, (("fridge", 0.6, 0.65, 1.8, 0.7),))
    base = _against(f"{name}_base", room.box, side, lo, length, 0.6, 0.9)
    upper = _against(f"{name}_upper", room.box, side, lo, length, 0.35, 0.7, z0=1.45)
    return [base, upper]


#: Chance that a doorway gets a lintel, and the height range (m) of the lintel's underside: doors are 2.0-2.3 m
#: high in most buildings; a strip under 0.2 m is left out.
LINTEL_CHANCE = 0.8
LINTEL_UNDERSIDE_M = (2.0, 2.3)


def lintels(plan: Plan, rng: np.random.Generator) -> list[dict[str, Any]]:
    """A strip of wall (class wall) over most doorways of ``plan``, from 2.0-2.3 m up to the higher ceiling of
    the rooms the doorway joins, the wall's thickness: the doorway's opening then stops short of the ceiling, as
    in most real buildings. Not in the occupancy map (``occupancy: false``): above the LiDAR's and the robot's
    reach, like the map a user draws of such a building."""
    elements: list[dict[str, Any]] = []
    reach = plan.wall + 0.01  # a room the doorway joins ends within the wall's thickness of it
    for k, (x0, y0, x1, y1) in enumerate(plan.doors):
        underside = float(rng.uniform(*LINTEL_UNDERSIDE_M))
        if rng.random() >= LINTEL_CHANCE:
            continue
        joined = [
            r.ceiling
            for r in plan.rooms
            if r.box[0] < x1 + reach and x0 - reach < r.box[2] and r.box[1] < y1 + reach and y0 - reach < r.box[3]
        ]
        top = max(joined, default=0.0)
        if top - underside < 0.2:
            continue
        element = _box(f"lintel_{k}", (x0, y0, underside), (x1, y1, top), "wall")
        element["occupancy"] = False
        elements.append(element)
    return elements
