"""nav2's beam model and likelihood_field_prob: per-beam probabilities against hand-computed values, the ray
caster against the room it casts in, and both models through AMCL."""

import numpy as np
import pytest

from pimm_agents.amcl.localizer import Amcl, AmclConfig
from pimm_agents.factory import resolve_config
from pimm_agents.particles.beam_model import BeamModel, BeamModelParams, RangeCaster, RangeTable, beam_probabilities
from pimm_agents.particles.likelihood_field import BeamSkip, LikelihoodField, LikelihoodFieldParams
from pimm_env.mapping.occupancy import OccupancyGrid
from pimm_env.world.grid import GridSpec
from tests.rooms import box_room, observation


def room_with_unknown() -> OccupancyGrid:
    """4 m x 3 m of free cells inside a one-cell wall, except the strip x > 3.5 m, which is unknown."""
    grid = GridSpec((0.0, 0.0), 0.05, (60, 80))
    occupied = grid.empty_mask()
    occupied[[0, -1], :] = True
    occupied[:, [0, -1]] = True
    free = ~occupied
    free[:, 70:] = False
    return OccupancyGrid(grid, occupied, free)


def test_beam_probability_is_navs_sum_of_four_parts_hand_computed():
    # z = 2.0 - 2.1 = -0.1: hit 0.5 exp(-0.01 / 0.08) = 0.441248, short 0.05 * 0.1 * exp(-0.2) = 0.004094,
    # random 0.5 / 10 = 0.05
    assert beam_probabilities(np.array(2.0), np.array(2.1), 10.0) == pytest.approx(0.495342, abs=1e-6)
    # longer than expected: no short part; 0.441248 + 0.05
    assert beam_probabilities(np.array(2.2), np.array(2.1), 10.0) == pytest.approx(0.491248, abs=1e-6)
    # a max-range reading 6 m past the wall: only z_max (hit exp(-450) is nothing), no random part
    assert beam_probabilities(np.array(10.0), np.array(4.0), 10.0) == pytest.approx(0.05, abs=1e-12)
    # 2 m short of the wall at 5 m: hit ~0, short 0.005 exp(-0.1 * 3) = 0.0037041, random 0.05
    assert beam_probabilities(np.array(3.0), np.array(5.0), 10.0) == pytest.approx(0.0537041, abs=1e-6)
    params = BeamModelParams(z_hit=0.8, z_short=0.0, z_max=0.0, z_rand=0.2, sigma_hit=0.1, lambda_short=1.0)
    # 0.8 exp(-0.01 / 0.02) + 0.2 / 10 = 0.485225 + 0.02
    assert beam_probabilities(np.array(1.0), np.array(1.1), 10.0, params) == pytest.approx(0.505225, abs=1e-6)


def test_ranges_stop_at_walls_unknown_cells_and_the_map_edge():
    caster = RangeCaster(room_with_unknown(), range_max=10.0)
    pose = np.array([[1.0, 1.5, 0.0]])
    bearings = np.array([0.0, np.pi / 2, np.pi, -np.pi / 2, np.pi / 4])
    ranges = caster.ranges(pose, bearings)[0]
    # east: the unknown strip begins at x = 3.5; north: wall cell row 59 (y >= 2.95); west: x < 0.05; south
    expected = [2.5, 1.45, 0.95, 1.45, np.hypot(1.45, 1.45)]
    np.testing.assert_allclose(ranges, expected, atol=0.04)
    # from the mount offset: the sensor 0.2 m ahead of the robot's centre sees the east edge 0.2 m nearer
    assert caster.ranges(pose, bearings[:1], origin=(0.2, 0.0))[0, 0] == pytest.approx(2.3, abs=0.04)
    # a short range_max caps the ray; a sensor inside a wall reads 0
    assert RangeCaster(room_with_unknown(), 1.0).ranges(pose, bearings[:1])[0, 0] == pytest.approx(1.0)
    assert caster.ranges(np.array([[0.01, 1.5, 0.0]]), bearings[:1])[0, 0] == 0.0


def test_beam_model_prefers_the_true_pose_and_counts_no_returns_as_max_readings():
    room = box_room()
    model = BeamModel(room, range_max=10.0)
    truth, off = np.array([1.0, 1.5, 0.0]), np.array([1.3, 1.5, 0.0])
    bearings = np.linspace(-np.pi, np.pi, 36, endpoint=False)
    ranges = model.caster.ranges(truth[None], bearings)[0]
    factors = model.weight_factors(np.stack([truth, off]), ranges, bearings)
    assert factors[0] > factors[1] > 1.0
    pz = beam_probabilities(ranges, ranges, 10.0)  # at the truth every beam is a hit
    assert factors[0] == pytest.approx(1 + np.sum(pz**3), rel=1e-9)
    # a beam with no return weighs as max range: z_max + hit part of a 10 m reading
    one = model.weight_factors(truth[None], np.array([10.0]), np.array([0.0]))[0]
    assert one == pytest.approx(1 + 0.05**3, rel=1e-6)


def test_range_table_gives_the_cast_range_at_cell_centres_and_table_headings():
    room = room_with_unknown()
    table, caster = RangeTable(room, 10.0, headings=72), RangeCaster(room, 10.0)
    assert table.table.dtype == np.uint8 and table.table.shape == (int(room.free.sum()), 72)
    rng = np.random.default_rng(0)
    rows, cols = np.nonzero(room.free)
    pick = rng.choice(len(rows), 50, replace=False)
    centres = np.stack([(cols[pick] + 0.5) * 0.05, (rows[pick] + 0.5) * 0.05, rng.uniform(-np.pi, np.pi, 50)], 1)
    centres[:, 2] = np.round(centres[:, 2] / (2 * np.pi / 72)) * (2 * np.pi / 72)  # headings on the table's
    bearings = np.arange(0, 72, 5) * (2 * np.pi / 72) - np.pi
    np.testing.assert_allclose(table.ranges(centres, bearings), caster.ranges(centres, bearings), atol=0.025 + 1e-9)
    # elsewhere the cell and the heading are rounded: within a cell and the heading's half step of arc
    poses = np.stack([rng.uniform(0.1, 3.4, 200), rng.uniform(0.1, 2.9, 200), rng.uniform(-np.pi, np.pi, 200)], 1)
    gap = np.abs(table.ranges(poses, bearings) - caster.ranges(poses, bearings))
    assert np.median(gap) < 0.05
    # a sensor in a wall or off the map reads 0, as the caster does
    assert table.ranges(np.array([[0.01, 1.5, 0.0], [-1.0, 1.0, 0.0]]), bearings[:1]).tolist() == [[0.0], [0.0]]


def test_beam_model_weighs_table_ranges_as_the_formula_does_and_agrees_with_exact_casting():
    room = box_room()
    table, exact = BeamModel(room, 10.0, headings=360), BeamModel(room, 10.0, headings=0)
    rng = np.random.default_rng(1)
    poses = np.stack([rng.uniform(0.2, 3.8, 300), rng.uniform(0.2, 2.8, 300), rng.uniform(-np.pi, np.pi, 300)], 1)
    bearings = np.linspace(-np.pi, np.pi, 60, endpoint=False)
    scan = exact.caster.ranges(np.array([[1.0, 1.5, 0.3]]), bearings)[0]
    # the table's factors are the formula applied to the table's ranges (the per-cell gather loses nothing)
    expected = 1 + (beam_probabilities(scan[None, :], table.caster.ranges(poses, bearings), 10.0) ** 3).sum(1)
    np.testing.assert_allclose(table.weight_factors(poses, scan, bearings), expected, rtol=1e-9)
    # and they rank the poses as exact casting does
    a, b = table.weight_factors(poses, scan, bearings), exact.weight_factors(poses, scan, bearings)
    assert np.corrcoef(np.log(a), np.log(b))[0, 1] > 0.95


def field_one_wall() -> LikelihoodField:
    grid = GridSpec.covering(np.array([0.0, 0.0]), np.array([4.0, 4.0]), 0.1, margin=0.5)
    gx, gy = grid.cell_centers()
    occupied = (np.abs(gx - 3.0) < 0.05) & (gy > 0) & (gy < 4)  # one wall, x = 3
    return LikelihoodField(OccupancyGrid(grid, occupied, ~occupied), LikelihoodFieldParams(0.5, 0.5, 0.2, 2.0, 10.0))


def test_likelihood_field_prob_multiplies_pz_and_skips_beams_most_particles_do_not_fit():
    field = field_one_wall()
    poses = np.array([[1.0, 2.0, 0.0], [1.0, 2.5, 0.0], [1.0, 1.5, 0.0]])
    # beam 0 ends on the wall for every pose; beam 1 (to the north-west) ends in open space 1.5 m from it
    ranges, bearings = np.array([2.0, 1.0]), np.array([0.0, np.pi * 0.75])
    d0 = field.distance_at(np.array([[3.0, 2.0]]))[0]
    d1 = field.distance_at(np.array([[1.0 - np.sqrt(0.5), 2.0 + np.sqrt(0.5)]]))[0]
    assert d1 > 0.5
    pz = 0.5 * np.exp(-(np.array([d0, d1]) ** 2) / 0.08) + 0.05
    product = field.prob_factors(poses, ranges, bearings)
    assert product[0] == pytest.approx(pz[0] * pz[1], rel=1e-5)
    # beam skipping: beam 1 fits no particle (0 of 3 within 0.5 m of an obstacle), so only beam 0 counts
    skipped = field.prob_factors(poses, ranges, bearings, skip=BeamSkip())
    assert skipped[0] == pytest.approx(pz[0], rel=1e-5)
    # ... unless too many beams would go (error threshold): with 0.4, 1 skipped of 2 is too many; all count
    kept = field.prob_factors(poses, ranges, bearings, skip=BeamSkip(error_threshold=0.4))
    np.testing.assert_allclose(kept, product)


@pytest.mark.parametrize("name,model", [("amcl-beam", "beam"), ("amcl-lfp", "likelihood_field_prob")])
def test_presets_run_through_the_contract_without_nan(name, model):
    config = resolve_config(name)
    assert config.laser_model_type == model and config.do_beamskip == (name == "amcl-lfp")
    assert (config.z_short, config.z_max, config.lambda_short, config.beam_skip_distance) == (0.05, 0.05, 0.1, 0.5)
    amcl = Amcl(box_room(), AmclConfig(**{**config.__dict__, "max_particles": 300, "min_particles": 100}))
    amcl.reset(seed=0, initial_pose=np.array([1.0, 1.5, 0.0]), initial_cov=np.diag([0.01, 0.01, 0.001]))
    bearings = np.linspace(-np.pi, np.pi, 360, endpoint=False)
    scan = RangeCaster(box_room(), 10.0).ranges(np.array([[1.0, 1.5, 0.0]]), bearings)[0]
    scan[::7] = np.nan
    scan[1::7] = np.inf
    for step in range(3):
        estimate = amcl.update(observation(scan, odom=(0.0, 0.0, 0.3 * step), t=0.1 * step))
        assert np.all(np.isfinite(estimate.pose)) and np.all(np.isfinite(estimate.covariance))
    assert np.hypot(estimate.pose[0] - 1.0, estimate.pose[1] - 1.5) < 0.3


def test_unknown_laser_model_is_named():
    with pytest.raises(ValueError, match="laser_model_type must be one of likelihood_field, beam"):
        AmclConfig(laser_model_type="beams")
