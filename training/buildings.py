"""Procedural buildings for training and for held-out evaluation, one per seed.

Four families, drawn per seed: ``offices`` (a corridor with rows of identical offices on one or both sides),
``hall`` (a high hall with columns and beams, and a row of low rooms along it), ``L`` and ``U`` (corridors at
right angles with offices along them). Ceilings are 2.4-3.0 m in offices and corridors and 4-8 m in halls, so
scans see ceiling steps; offices are 2.4-4.5 m wide, so walls are often within 1 m; rooms in a row are
identical, with the door at the same place, so places look alike. Each room gets seeded furniture (desks,
cabinets), halls get columns and beams.

The plan is drawn as free-space rectangles on a 0.05 m raster and turned into a world with the same importer
that reads ROS maps, so a generated building is exactly what a user's imported floor plan becomes.

Three furnished families (``training/furnished.py``) are drawn only for their own seeds
(``FURNISHED_TRAINING_SEEDS``, ``FURNISHED_HELD_OUT_SEEDS``; and with lintels over their doorways,
``LINTEL_TRAINING_SEEDS``, ``LINTEL_HELD_OUT_SEEDS``): ``home`` (a hallway with living rooms,
bedrooms, kitchens and bathrooms on both sides), ``shop`` (a sales floor with shelving along its walls,
free-standing shelf rows and a counter, and a store room behind it) and ``ward`` (a corridor of patient rooms,
alike as a ward's are, and a nurses' station behind a glass partition). Their rooms are furnished by kind
against the walls, leaving every doorway free: the rooms users live and work in, where walls stand behind
furniture.

Two look-alike families are drawn only for their own seeds: ``periodic`` (a long corridor of identical
bays: offices on both sides, pillars at every bay, and only its two ends differ, one closed, one opening
into a lobby; the rows are longer than the LiDAR sees) and ``mirror`` (a lobby with two identical wings,
the floor the same turned half a turn about the lobby's centre, so every place has an exact twin, except for
one store room off the lobby). They are where a localizer must say ``ambiguous`` rather than pick a twin.

The seeds used for training and those kept for evaluation are fixed here: no training or tuning may use
``NEVER_TRAIN_SEEDS`` (``HELD_OUT_SEEDS``, ``LOCALIZER_HELD_OUT_SEEDS``, ``LOOKALIKE_HELD_OUT_SEEDS``,
``FURNISHED_HELD_OUT_SEEDS``).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from training.furnished import draw_home, draw_shop, draw_ward, furnish, lintels
from training.plans import DOOR, RES, Plan, Room
from training.suites import seeds_of, suite

# The buildings of each suite (training/suites/suites.yaml says what each is for and when it may be used).
TRAINING_SEEDS = suite("training").seeds
DEVELOPMENT_SEEDS = suite("generated-development").seeds
HELD_OUT_SEEDS = suite("network-held-out").seeds
LOCALIZER_HELD_OUT_SEEDS = suite("generated-held-out").seeds
LOOKALIKE_DEVELOPMENT_SEEDS = suite("lookalike-development").seeds
LOOKALIKE_HELD_OUT_SEEDS = suite("lookalike-held-out").seeds
FURNISHED_TRAINING_SEEDS = suite("furnished-training").seeds
FURNISHED_HELD_OUT_SEEDS = suite("furnished-held-out").seeds
LINTEL_TRAINING_SEEDS = suite("lintel-training").seeds
LINTEL_HELD_OUT_SEEDS = suite("lintel-held-out").seeds
#: Seeds no training may use: every held-out suite's.
NEVER_TRAIN_SEEDS = seeds_of("held-out")
#: where active-localization policies are trained: training buildings and look-alike development buildings
#: (970-977, the look-alike seeds the localizer was tuned on, stay out so that they can judge a policy too)
POLICY_TRAINING_SEEDS = TRAINING_SEEDS[:8] + LOOKALIKE_DEVELOPMENT_SEEDS[:16]
FURNISHED_SEEDS = FURNISHED_TRAINING_SEEDS + FURNISHED_HELD_OUT_SEEDS + LINTEL_TRAINING_SEEDS + LINTEL_HELD_OUT_SEEDS
LINTEL_SEEDS = LINTEL_TRAINING_SEEDS + LINTEL_HELD_OUT_SEEDS
FAMILIES = ("offices", "hall", "L", "U")
LOOKALIKE_FAMILIES = ("periodic", "mirror")
FURNISHED_FAMILIES = ("home", "shop", "ward")


def _corridor_with_offices(
    rng: np.random.Generator,
    origin: tuple[float, float],
    length: float,
    along_x: bool,
    sides: tuple[int, ...],
    plan: Plan,
    ceiling: float,
) -> None:
    """A corridor from ``origin`` along x (or y), with a row of identical offices on each of ``sides`` (+1/-1)."""
    width = rng.uniform(1.5, 2.4)
    t = plan.wall
    x0, y0 = origin
    corridor = (x0, y0, x0 + length, y0 + width) if along_x else (x0, y0, x0 + width, y0 + length)
    plan.rooms.append(Room(corridor, ceiling, "corridor"))
    office_w, office_d = rng.uniform(2.4, 4.5), rng.uniform(3.0, 5.5)
    office_h = rng.uniform(2.4, 3.0)
    door_at = rng.uniform(0.2, max(0.25, office_w - 1.1))  # the same in every office: look-alike rooms
    count = int(length // (office_w + t))
    for side in sides:
        for k in range(count):
            a = k * (office_w + t)
            if along_x:
                ys = (y0 + width + t, y0 + width + t + office_d) if side > 0 else (y0 - t - office_d, y0 - t)
                box = (x0 + a, ys[0], x0 + a + office_w, ys[1])
                wall_y = (y0 + width, y0 + width + t) if side > 0 else (y0 - t, y0)
                door = (x0 + a + door_at, wall_y[0], x0 + a + door_at + 0.9, wall_y[1])
            else:
                xs = (x0 + width + t, x0 + width + t + office_d) if side > 0 else (x0 - t - office_d, x0 - t)
                box = (xs[0], y0 + a, xs[1], y0 + a + office_w)
                wall_x = (x0 + width, x0 + width + t) if side > 0 else (x0 - t, x0)
                door = (wall_x[0], y0 + a + door_at, wall_x[1], y0 + a + door_at + 0.9)
            if not _overlaps(box, plan, t):
                plan.rooms.append(Room(box, office_h, "office"))
                plan.doors.append(door)


def _overlaps(box: tuple[float, float, float, float], plan: Plan, margin: float) -> bool:
    x0, y0, x1, y1 = box
    for room in plan.rooms:
        a0, b0, a1, b1 = room.box
        if x0 < a1 + margin - 1e-9 and a0 < x1 + margin - 1e-9 and y0 < b1 + margin - 1e-9 and b0 < y1 + margin - 1e-9:
            return True
    return False


def _periodic(rng: np.random.Generator, plan: Plan, ceiling: float) -> None:
    """A corridor of 7-10 identical bays along x: an office on each side of every bay, a pillar pair at every
    bay's end; closed at x = 0, opening into a lobby at the far end."""
    t = plan.wall
    bay, bays = float(rng.uniform(4.0, 6.0)), int(rng.integers(7, 11))
    width, depth = float(rng.uniform(1.8, 2.6)), float(rng.uniform(3.5, 5.0))
    door_at = float(rng.uniform(0.3, bay - DOOR - 0.3))
    length = bays * (bay + t) - t
    plan.rooms.append(Room((0.0, 0.0, length, width), ceiling, "corridor"))
    for k in range(bays):
        a = k * (bay + t)
        plan.rooms.append(Room((a, width + t, a + bay, width + t + depth), ceiling, "office"))
        plan.doors.append((a + door_at, width, a + door_at + DOOR, width + t))
        plan.rooms.append(Room((a, -t - depth, a + bay, -t), ceiling, "office"))
        plan.doors.append((a + door_at, -t, a + door_at + DOOR, 0.0))
        if k:
            plan.pillars += [(a - t / 2, 0.2), (a - t / 2, width - 0.2)]
    lobby = float(rng.uniform(5.0, 8.0))
    plan.rooms.append(
        Room((length + t, -lobby / 2 + width / 2, length + t + lobby, lobby / 2 + width / 2), ceiling, "hall")
    )
    plan.doors.append((length, 0.2, length + t, width - 0.2))


def _mirror(rng: np.random.Generator, plan: Plan, ceiling: float) -> None:
    """A lobby centred on the origin and two wings, each the other turned half a turn about the origin (offices
    on both sides of a corridor), and one store room off the lobby that has no twin."""
    t = plan.wall
    half_w, half_d = float(rng.uniform(2.5, 4.0)), float(rng.uniform(2.5, 4.0))
    plan.rooms.append(Room((-half_w, -half_d, half_w, half_d), ceiling, "hall"))
    width = float(rng.uniform(1.8, 2.4))
    office, depth, count = float(rng.uniform(3.0, 4.5)), float(rng.uniform(3.5, 5.0)), int(rng.integers(3, 6))
    door_at = float(rng.uniform(0.3, office - DOOR - 0.3))
    wing: list[Room] = [
        Room((half_w + t, -width / 2, half_w + t + count * (office + t), width / 2), ceiling, "corridor")
    ]
    doors = [(half_w, -width / 2 + 0.2, half_w + t, width / 2 - 0.2)]
    for k in range(count):
        a = half_w + t + k * (office + t)
        wing.append(Room((a, width / 2 + t, a + office, width / 2 + t + depth), ceiling, "office"))
        doors.append((a + door_at, width / 2, a + door_at + DOOR, width / 2 + t))
        wing.append(Room((a, -width / 2 - t - depth, a + office, -width / 2 - t), ceiling, "office"))
        doors.append((a + office - door_at - DOOR, -width / 2 - t, a + office - door_at, -width / 2))
    for room in wing:
        x0, y0, x1, y1 = room.box
        plan.rooms += [room, Room((-x1, -y1, -x0, -y0), room.ceiling, room.kind)]
    for x0, y0, x1, y1 in doors:
        plan.doors += [(x0, y0, x1, y1), (-x1, -y1, -x0, -y0)]
    store = float(rng.uniform(2.0, 3.0))
    x = float(rng.uniform(-half_w, half_w - store))
    plan.rooms.append(Room((x, half_d + t, x + store, half_d + t + store), ceiling, "office"))
    plan.doors.append((x + 0.1, half_d, x + 0.1 + DOOR, half_d + t))


def draw_plan(seed: int) -> tuple[str, Plan]:
    """The rooms and doors of building ``seed``."""
    rng = np.random.default_rng(seed)
    if seed in FURNISHED_SEEDS:
        family = FURNISHED_FAMILIES[int(rng.integers(len(FURNISHED_FAMILIES)))]
        plan = Plan([], [], float(rng.uniform(0.1, 0.25)))
        {"home": draw_home, "shop": draw_shop, "ward": draw_ward}[family](rng, plan, float(rng.uniform(2.4, 3.0)))
        return family, plan
    if seed in LOOKALIKE_DEVELOPMENT_SEEDS + LOOKALIKE_HELD_OUT_SEEDS:
        family = LOOKALIKE_FAMILIES[int(rng.integers(len(LOOKALIKE_FAMILIES)))]
        plan = Plan([], [], float(rng.uniform(0.1, 0.25)))
        (_periodic if family == "periodic" else _mirror)(rng, plan, float(rng.uniform(2.4, 3.0)))
        return family, plan
    family = FAMILIES[int(rng.integers(len(FAMILIES)))]
    plan = Plan([], [], float(rng.uniform(0.1, 0.25)))
    ceiling = float(rng.uniform(2.4, 3.0))
    if family == "offices":
        _corridor_with_offices(
            rng, (0.0, 0.0), rng.uniform(16, 36), True, (1, -1) if rng.random() < 0.7 else (1,), plan, ceiling
        )
    elif family == "hall":
        w, d = rng.uniform(10, 22), rng.uniform(8, 16)
        plan.rooms.append(Room((0.0, 0.0, w, d), float(rng.uniform(4.0, 8.0)), "hall"))
        t = plan.wall
        _corridor_with_offices(rng, (0.0, d + t), w, True, (1,), plan, ceiling)
        plan.doors.append((w / 2 - 0.8, d, w / 2 + 0.8, d + t))  # wide opening from the hall to the corridor
    else:
        a = rng.uniform(14, 26)
        _corridor_with_offices(rng, (0.0, 0.0), a, True, (-1,), plan, ceiling)
        first = plan.rooms[0].box
        _corridor_with_offices(rng, (first[2], first[1]), rng.uniform(12, 22), False, (1,), plan, ceiling)
        if family == "U":
            second = [r for r in plan.rooms if r.kind == "corridor"][1].box
            _corridor_with_offices(rng, (second[2] - a, second[3]), a, True, (1,), plan, ceiling)
    return family, plan


def plan_raster(plan: Plan) -> tuple[np.ndarray, np.ndarray, tuple[float, float]]:
    """Free and occupied cells of the plan at 0.05 m, with 1 m of solid around it, and the grid's origin."""
    boxes = np.array([r.box for r in plan.rooms] + plan.doors)
    lo, hi = boxes[:, :2].min(axis=0) - 1.0, boxes[:, 2:].max(axis=0) + 1.0
    cols, rows = np.ceil((hi - lo) / RES).astype(int)
    free = np.zeros((rows, cols), dtype=bool)
    for x0, y0, x1, y1 in boxes:
        c0, c1 = round((x0 - lo[0]) / RES), round((x1 - lo[0]) / RES)
        r0, r1 = round((y0 - lo[1]) / RES), round((y1 - lo[1]) / RES)
        free[r0:r1, c0:c1] = True
    return free, ~free, (float(lo[0]), float(lo[1]))


def _hall_fixtures(plan: Plan, rng: np.random.Generator) -> list[dict[str, Any]]:
    """Columns on a grid and beams under the ceiling of each hall (class clutter, as the iilab's)."""
    elements: list[dict[str, Any]] = []
    for room in plan.rooms:
        if room.kind != "hall":
            continue
        x0, y0, x1, y1 = room.box
        spacing = rng.uniform(4.0, 6.5)
        xs = np.arange(x0 + spacing, x1 - 1.5, spacing)
        ys = np.arange(y0 + spacing, y1 - 1.5, spacing)
        square = rng.random() < 0.5
        for i, x in enumerate(xs):
            for j, y in enumerate(ys):
                name = f"column_{i}_{j}"
                if square:
                    elements.append(
                        {
                            "name": name,
                            "class": "clutter",
                            "box": {
                                "center": [round(x, 3), round(y, 3), room.ceiling / 2],
                                "size": [0.4, 0.4, room.ceiling],
                            },
                        }
                    )
                else:
                    elements.append(
                        {
                            "name": name,
                            "class": "clutter",
                            "cylinder": {
                                "center": [round(x, 3), round(y, 3)],
                                "radius": 0.25,
                                "z": [0.0, room.ceiling],
                            },
                        }
                    )
        if rng.random() < 0.6:
            for i, x in enumerate(xs):
                elements.append(
                    {
                        "name": f"beam_{i}",
                        "class": "clutter",
                        "box": {"min": [x - 0.15, y0, room.ceiling - 0.5], "max": [x + 0.15, y1, room.ceiling]},
                    }
                )
    return elements


def _room_furniture(plan: Plan, rng: np.random.Generator) -> list[dict[str, Any]]:
    """A desk against the back wall of most offices, a cabinet in some: the same in every office of a row."""
    elements: list[dict[str, Any]] = []
    has_desk, has_cabinet = rng.random() < 0.8, rng.random() < 0.5
    for k, room in enumerate(r for r in plan.rooms if r.kind == "office"):
        x0, y0, x1, y1 = room.box
        cx, cy = (x0 + x1) / 2, (y0 + y1) / 2
        if has_desk:
            elements.append(
                {
                    "name": f"desk_{k}",
                    "class": "clutter",
                    "box": {"center": [round(cx, 3), round(cy, 3), 0.375], "size": [1.2, 0.6, 0.75]},
                }
            )
        if has_cabinet:
            elements.append(
                {
                    "name": f"cabinet_{k}",
                    "class": "clutter",
                    "box": {"center": [round(x0 + 0.3, 3), round(y0 + 0.6, 3), 0.95], "size": [0.45, 0.9, 1.9]},
                }
            )
    return elements


def _pillars(plan: Plan) -> list[dict[str, Any]]:
    """The plan's pillars, floor to the corridor's ceiling (class clutter, as the halls' columns)."""
    height = max((r.ceiling for r in plan.rooms if r.kind == "corridor"), default=2.5)
    return [
        {
            "name": f"pillar_{k}",
            "class": "clutter",
            "box": {"center": [round(x, 3), round(y, 3), height / 2], "size": [0.4, 0.4, height]},
        }
        for k, (x, y) in enumerate(plan.pillars)
    ]


def building_spec(seed: int) -> dict[str, Any]:
    """The ``pimm-world/1`` mapping of building ``seed`` (deterministic)."""
    from pimm_env.importers.floor_plan import CeilingArea, world_spec
    from pimm_env.importers.vectorize import vectorize
    from pimm_env.mapping.map_server import RasterMap

    family, plan = draw_plan(seed)
    rng = np.random.default_rng([seed, 1])
    free, occupied, origin = plan_raster(plan)
    raster = RasterMap(occupied, free, RES, (origin[0], origin[1], 0.0), Path(f"<building {seed}>"))
    floor_plan = vectorize(raster)
    h = plan.wall / 2
    ceilings = [
        CeilingArea(
            f"{r.kind}_{k}",
            np.array(
                [
                    [r.box[0] - h, r.box[1] - h],
                    [r.box[2] + h, r.box[1] - h],
                    [r.box[2] + h, r.box[3] + h],
                    [r.box[0] - h, r.box[3] + h],
                ]
            ),
            r.ceiling,
        )
        for k, r in enumerate(plan.rooms)
    ]
    default = max(r.ceiling for r in plan.rooms if r.kind == "corridor" or family == "shop")
    spec = world_spec(f"{family}-{seed}", floor_plan, default, ceilings)
    spec["elements"] += _hall_fixtures(plan, rng) + _room_furniture(plan, rng) + _pillars(plan) + furnish(plan, rng)
    if seed in LINTEL_SEEDS:
        spec["elements"] += lintels(plan, np.random.default_rng([seed, 2]))
    return spec


def write_building(seed: int, maps_dir: Path) -> Path:
    """Write ``maps_dir/gen-SEED/world.yaml``; returns its path."""
    from pimm_env.importers.floor_plan import write_world

    spec = building_spec(seed)
    spec["name"] = f"gen-{seed}"
    return write_world(spec, Path(maps_dir) / f"gen-{seed}" / "world.yaml")
