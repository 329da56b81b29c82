from pimm_env.world.files import world_from_spec
from pimm_env.world.semantics import SemanticClass
from training.buildings import (
    DEVELOPMENT_SEEDS,
    FAMILIES,
    HELD_OUT_SEEDS,
    LOCALIZER_HELD_OUT_SEEDS,
    LOOKALIKE_DEVELOPMENT_SEEDS,
    LOOKALIKE_HELD_OUT_SEEDS,
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
