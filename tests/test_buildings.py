import numpy as np
import pytest

from pimm_env.world.files import world_from_spec
from pimm_env.world.semantics import SemanticClass
from training.buildings import (
    FAMILIES,
    FURNISHED_FAMILIES,
    FURNISHED_HELD_OUT_SEEDS,
    FURNISHED_TRAINING_SEEDS,
    LINTEL_TRAINING_SEEDS,
    LOOKALIKE_DEVELOPMENT_SEEDS,
    LOOKALIKE_HELD_OUT_SEEDS,
    NEVER_TRAIN_SEEDS,
    TRAINING_SEEDS,
    building_spec,
    draw_plan,
)
from training.suites import SuiteError, parse_seeds, subset, suite, suites


def test_the_generator_is_deterministic_per_seed_and_the_suites_keep_their_buildings_apart():
    assert building_spec(101) == building_spec(101)
    seeded = [x for x in suites().values() if x.seeds]
    for i, first in enumerate(seeded):  # no building is in two suites: a held-out one was never looked at
        for other in seeded[i + 1 :]:
            assert not set(first.seeds) & set(other.seeds), (first.name, other.name)
    held = {s for x in seeded if x.kind == "held-out" for s in x.seeds}
    assert held == set(NEVER_TRAIN_SEEDS) and not held & set(TRAINING_SEEDS + FURNISHED_TRAINING_SEEDS)
    assert {draw_plan(seed)[0] for seed in LOOKALIKE_HELD_OUT_SEEDS + LOOKALIKE_DEVELOPMENT_SEEDS} <= {
        "periodic",
        "mirror",
    }
    assert len(suite("lookalike-held-out").seeds) == 96 and set(FURNISHED_HELD_OUT_SEEDS) <= held
    assert {x.name for x in suites().values() if x.commands} == {
        "iilab-thesis",
        "every-localizer",
        "perception",
        "real-plans-development",
        "real-plans-kidnaps",
        "real-laser-logs",
    }


def test_suites_name_what_is_wrong():
    assert parse_seeds(["3-5", "9"]) == (3, 4, 5, 9)
    assert subset(suite("generated-held-out"), [925, 921]) == (921, 925)
    with pytest.raises(SuiteError, match=r"seeds \[100\] are not buildings of suite 'generated-held-out'"):
        subset(suite("generated-held-out"), [100, 921])
    with pytest.raises(SuiteError, match="'5-3' runs backwards"):
        parse_seeds(["5-3"])
    with pytest.raises(SuiteError, match="no suite 'nope'; suites: training"):
        suite("nope")


def test_generated_buildings_cover_the_families_low_ceilings_and_look_alike_rooms():
    families = {draw_plan(seed)[0] for seed in TRAINING_SEEDS}
    assert families == set(FAMILIES)
    for seed in (100, 101, 107):
        _, plan = draw_plan(seed)
        offices = [r for r in plan.rooms if r.kind == "office"]
        widths = {round(min(r.box[2] - r.box[0], r.box[3] - r.box[1]), 6) for r in offices}
        corridors = [r for r in plan.rooms if r.kind == "corridor"]
        assert len(offices) >= 3 and len(widths) <= len(corridors), "the offices of a row are all alike"
        assert all(2.4 <= r.ceiling <= 3.0 for r in offices)
        world = world_from_spec(building_spec(seed), f"<building {seed}>")
        ceilings = world.ceiling_heights()
        assert min(ceilings) >= 2.4 and max(ceilings) <= 8.0
        assert any(e.semantic == SemanticClass.CLUTTER for e in world.elements)


def test_furnished_buildings_stand_their_furniture_against_the_walls_and_leave_the_doors_free():
    assert {draw_plan(seed)[0] for seed in FURNISHED_TRAINING_SEEDS} == set(FURNISHED_FAMILIES)
    for family in FURNISHED_FAMILIES:
        seed = next(s for s in FURNISHED_TRAINING_SEEDS if draw_plan(s)[0] == family)
        _, plan = draw_plan(seed)
        spec = building_spec(seed)
        world = world_from_spec(spec, f"<building {seed}>")
        furniture = [e for e in spec["elements"] if e["class"] == "clutter" and "min" in e.get("box", {})]
        assert len(furniture) >= 10, family
        against = 0
        for element in furniture:
            (x0, y0, _), (x1, y1, _) = element["box"]["min"], element["box"]["max"]
            inside = [r.box for r in plan.rooms if r.box[0] - 1e-3 <= x0 and x1 <= r.box[2] + 1e-3]
            room = next(b for b in inside if b[1] - 1e-3 <= y0 and y1 <= b[3] + 1e-3)  # in one room
            against += any(abs(a - b) < 1e-3 for a, b in zip((x0, y0, x1, y1), room, strict=True))
            for dx0, dy0, dx1, dy1 in plan.doors:  # nothing in a doorway or within 0.8 m of it, either side
                grow_x, grow_y = (0.8, 0.0) if dx1 - dx0 < dy1 - dy0 else (0.0, 0.8)
                assert not (x0 < dx1 + grow_x and dx0 - grow_x < x1 and y0 < dy1 + grow_y and dy0 - grow_y < y1)
        assert against >= 0.6 * len(furniture), family
        assert any(e.semantic == SemanticClass.WALL and e.name.startswith("glass") for e in world.elements) == (
            family == "ward"
        )


def test_lintel_buildings_close_most_doorways_above_door_height_and_leave_the_other_seeds_as_they_were():
    assert {draw_plan(seed)[0] for seed in LINTEL_TRAINING_SEEDS} == set(FURNISHED_FAMILIES)
    for seed in LINTEL_TRAINING_SEEDS[:6]:
        _, plan = draw_plan(seed)
        spec = building_spec(seed)
        lintels = [e for e in spec["elements"] if e["name"].startswith("lintel")]
        assert len(lintels) >= 0.5 * len(plan.doors) and lintels, seed
        for element in lintels:
            (x0, y0, z0), (x1, y1, z1) = element["box"]["min"], element["box"]["max"]
            assert element["class"] == "wall" and element["occupancy"] is False
            assert 2.0 <= z0 <= 2.3 and z1 - z0 >= 0.2
            assert any(np.allclose((x0, y0, x1, y1), door, atol=1e-3) for door in plan.doors)  # over a doorway
            assert z1 in {round(r.ceiling, 3) for r in plan.rooms}  # up to a ceiling: no gap above it
        world = world_from_spec(spec, f"<building {seed}>")
        assert not any(e.occupancy for e in world.elements if e.name.startswith("lintel"))
    assert not any(e["name"].startswith("lintel") for e in building_spec(FURNISHED_TRAINING_SEEDS[0])["elements"])
