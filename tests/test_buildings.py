import numpy as np

from pimm_env.world.files import world_from_spec
from pimm_env.world.semantics import SemanticClass
from training.buildings import (
    DEVELOPMENT_SEEDS,
    FAMILIES,
    FURNISHED_FAMILIES,
    FURNISHED_HELD_OUT_SEEDS,
    FURNISHED_TRAINING_SEEDS,
    HELD_OUT_SEEDS,
    LINTEL_HELD_OUT_SEEDS,
    LINTEL_TRAINING_SEEDS,
    LOCALIZER_HELD_OUT_SEEDS,
    LOOKALIKE_ACTIVE_HELD_OUT_SEEDS,
    LOOKALIKE_CHECK_HELD_OUT_SEEDS,
    LOOKALIKE_CRITIC_HELD_OUT_SEEDS,
    LOOKALIKE_DEVELOPMENT_SEEDS,
    LOOKALIKE_DRIVER_HELD_OUT_SEEDS,
    LOOKALIKE_HELD_OUT_SEEDS,
    LOOKALIKE_MARGIN_HELD_OUT_SEEDS,
    LOOKALIKE_POLICY_HELD_OUT_SEEDS,
    LOOKALIKE_REFIT_HELD_OUT_SEEDS,
    LOOKALIKE_RETRAINED_POLICY_HELD_OUT_SEEDS,
    LOOKALIKE_SCAN_MARGIN_HELD_OUT_SEEDS,
    LOOKALIKE_SECOND_HELD_OUT_SEEDS,
    LOOKALIKE_TWIN_HELD_OUT_SEEDS,
    NEVER_TRAIN_SEEDS,
    TRAINING_SEEDS,
    building_spec,
    draw_plan,
)


def test_the_generator_is_deterministic_per_seed_and_keeps_held_out_seeds_apart():
    assert building_spec(101) == building_spec(101)
    assert building_spec(101) != building_spec(102)
    assert not set(TRAINING_SEEDS) & set(HELD_OUT_SEEDS) and not set(TRAINING_SEEDS) & set(DEVELOPMENT_SEEDS)
    assert not set(HELD_OUT_SEEDS) & set(DEVELOPMENT_SEEDS)
    looked_at = set(TRAINING_SEEDS) | set(DEVELOPMENT_SEEDS) | set(HELD_OUT_SEEDS) | set(LOOKALIKE_DEVELOPMENT_SEEDS)
    assert not looked_at & (set(LOCALIZER_HELD_OUT_SEEDS) | set(LOOKALIKE_HELD_OUT_SEEDS))
    assert {draw_plan(seed)[0] for seed in LOOKALIKE_HELD_OUT_SEEDS} <= {"periodic", "mirror"}
    second = set(LOOKALIKE_SECOND_HELD_OUT_SEEDS)
    assert {draw_plan(seed)[0] for seed in second} <= {"periodic", "mirror"} and second <= set(NEVER_TRAIN_SEEDS)
    assert not second & (looked_at | set(LOOKALIKE_HELD_OUT_SEEDS) | set(LOCALIZER_HELD_OUT_SEEDS))
    third = set(LOOKALIKE_ACTIVE_HELD_OUT_SEEDS)
    assert {draw_plan(seed)[0] for seed in third} <= {"periodic", "mirror"} and third <= set(NEVER_TRAIN_SEEDS)
    assert not third & (looked_at | second | set(LOOKALIKE_HELD_OUT_SEEDS) | set(LOCALIZER_HELD_OUT_SEEDS))
    fourth = set(LOOKALIKE_POLICY_HELD_OUT_SEEDS)
    assert {draw_plan(seed)[0] for seed in fourth} <= {"periodic", "mirror"} and fourth <= set(NEVER_TRAIN_SEEDS)
    assert not fourth & (looked_at | second | third | set(LOOKALIKE_HELD_OUT_SEEDS) | set(LOCALIZER_HELD_OUT_SEEDS))
    fifth = set(LOOKALIKE_CHECK_HELD_OUT_SEEDS)
    assert {draw_plan(seed)[0] for seed in fifth} <= {"periodic", "mirror"} and fifth <= set(NEVER_TRAIN_SEEDS)
    assert not fifth & (looked_at | second | third | fourth | set(LOOKALIKE_HELD_OUT_SEEDS))
    sixth = set(LOOKALIKE_TWIN_HELD_OUT_SEEDS)
    assert {draw_plan(seed)[0] for seed in sixth} <= {"periodic", "mirror"} and sixth <= set(NEVER_TRAIN_SEEDS)
    assert not sixth & (looked_at | second | third | fourth | fifth | set(LOOKALIKE_HELD_OUT_SEEDS))
    seventh = set(LOOKALIKE_MARGIN_HELD_OUT_SEEDS)
    assert {draw_plan(seed)[0] for seed in seventh} <= {"periodic", "mirror"} and seventh <= set(NEVER_TRAIN_SEEDS)
    assert not seventh & (looked_at | second | third | fourth | fifth | sixth | set(LOOKALIKE_HELD_OUT_SEEDS))
    eighth = set(LOOKALIKE_REFIT_HELD_OUT_SEEDS)
    assert {draw_plan(seed)[0] for seed in eighth} <= {"periodic", "mirror"} and eighth <= set(NEVER_TRAIN_SEEDS)
    assert not eighth & (looked_at | second | third | fourth | fifth | sixth | seventh | set(LOOKALIKE_HELD_OUT_SEEDS))
    earlier = second | third | fourth | fifth | sixth | seventh | eighth | set(LOOKALIKE_HELD_OUT_SEEDS)
    later_sets = (  # the ninth to the twelfth
        LOOKALIKE_RETRAINED_POLICY_HELD_OUT_SEEDS,
        LOOKALIKE_DRIVER_HELD_OUT_SEEDS,
        LOOKALIKE_SCAN_MARGIN_HELD_OUT_SEEDS,
        LOOKALIKE_CRITIC_HELD_OUT_SEEDS,
    )
    for later in later_sets:
        fresh = set(later)
        assert {draw_plan(seed)[0] for seed in fresh} <= {"periodic", "mirror"} and fresh <= set(NEVER_TRAIN_SEEDS)
        assert not fresh & (looked_at | earlier | set(LOCALIZER_HELD_OUT_SEEDS))
        earlier |= fresh
    seen = looked_at | set(LOCALIZER_HELD_OUT_SEEDS) | set(LOOKALIKE_HELD_OUT_SEEDS) | set(FURNISHED_TRAINING_SEEDS)
    assert not seen & set(FURNISHED_HELD_OUT_SEEDS) and set(FURNISHED_HELD_OUT_SEEDS) <= set(NEVER_TRAIN_SEEDS)
    assert not set(FURNISHED_TRAINING_SEEDS) & (set(TRAINING_SEEDS) | set(NEVER_TRAIN_SEEDS))
    lintels = set(LINTEL_TRAINING_SEEDS)
    assert not lintels & (seen | set(FURNISHED_HELD_OUT_SEEDS) | set(NEVER_TRAIN_SEEDS))
    assert set(LINTEL_HELD_OUT_SEEDS) <= set(NEVER_TRAIN_SEEDS) and not set(LINTEL_HELD_OUT_SEEDS) & (seen | lintels)


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
