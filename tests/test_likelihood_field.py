import numpy as np
import pytest

from pimm_agents.particles.likelihood_field import LikelihoodField, LikelihoodFieldParams
from pimm_env.mapping.occupancy import OccupancyGrid
from pimm_env.world.grid import GridSpec

PARAMS = LikelihoodFieldParams(z_hit=0.5, z_rand=0.5, sigma_hit=0.2, max_distance=0.6, range_max=10.0)


def small_map(seed: int = 0) -> OccupancyGrid:
    rng = np.random.default_rng(seed)
    grid = GridSpec((-1.0, 2.0), 0.1, (15, 20))
    occupied = rng.random(grid.shape) < 0.05
    return OccupancyGrid(grid, occupied, ~occupied)


def brute_distance(occ: OccupancyGrid, x: float, y: float) -> float:
    gx, gy = occ.grid.cell_centers()
    return float(np.min(np.hypot(gx[occ.occupied] - x, gy[occ.occupied] - y)))


def test_distance_field_matches_brute_force_and_is_capped():
    occ = small_map()
    field = LikelihoodField(occ, PARAMS)
    gx, gy = occ.grid.cell_centers()
    expected = np.array(
        [
            [min(brute_distance(occ, x, y), 0.6) for x, y in zip(rx, ry, strict=True)]
            for rx, ry in zip(gx, gy, strict=True)
        ]
    )
    np.testing.assert_allclose(field.distance, expected, atol=1e-9)
    assert field.distance.max() == pytest.approx(0.6)


def test_weight_factor_is_one_plus_sum_of_cubed_beam_likelihoods():
    occ = small_map(1)
    field = LikelihoodField(occ, PARAMS)
    rng = np.random.default_rng(2)
    poses = np.column_stack([rng.uniform(-1, 1, 5), rng.uniform(2, 3.5, 5), rng.uniform(-np.pi, np.pi, 5)])
    ranges = np.array([0.3, 0.8, 1.2, 5.0])  # the 5 m beam always ends off the map
    bearings = np.array([0.0, 1.0, -2.0, 0.5])
    for pose in poses:
        total = 1.0
        for r, b in zip(ranges, bearings, strict=True):
            end = pose[:2] + r * np.array([np.cos(pose[2] + b), np.sin(pose[2] + b)])
            inside = occ.grid.cells_of(end[None])[2][0]
            d = (
                field.distance[occ.grid.cells_of(end[None])[0][0], occ.grid.cells_of(end[None])[1][0]]
                if inside
                else 0.6
            )
            pz = 0.5 * np.exp(-(d**2) / (2 * 0.2**2)) + 0.5 / 10.0
            total += pz**3
        assert field.weight_factors(pose[None], ranges, bearings)[0] == pytest.approx(total, rel=1e-5)


def test_no_beams_leaves_weights_alone_and_an_empty_map_is_rejected():
    occ = small_map()
    field = LikelihoodField(occ, PARAMS)
    np.testing.assert_array_equal(field.weight_factors(np.zeros((3, 3)), np.zeros(0), np.zeros(0)), np.ones(3))
    empty = OccupancyGrid(occ.grid, np.zeros(occ.grid.shape, bool), np.ones(occ.grid.shape, bool))
    with pytest.raises(ValueError, match="no occupied cell"):
        LikelihoodField(empty, PARAMS)


def test_log_likelihoods_are_the_sum_of_log_pz_and_rank_poses_as_the_cubes_do():
    grid = GridSpec.covering(np.array([0.0, 0.0]), np.array([4.0, 4.0]), 0.1, margin=0.5)
    gx, gy = grid.cell_centers()
    occupied = (np.abs(gx - 3.0) < 0.05) & (gy > 0) & (gy < 4)  # one wall, x = 3
    field = LikelihoodField(OccupancyGrid(grid, occupied, ~occupied), LikelihoodFieldParams(0.5, 0.5, 0.2, 2.0, 10.0))
    poses = np.array([[1.0, 2.0, 0.0], [1.27, 2.0, 0.0]])  # the beams end on the wall from the first pose only
    ranges, bearings = np.array([2.0, 2.0]), np.array([0.0, 0.0])
    d = np.array([field.distance_at(np.array([[3.0, 2.0]]))[0], field.distance_at(np.array([[3.27, 2.0]]))[0]])
    pz = 0.5 * np.exp(-(d**2) / (2 * 0.2**2)) + 0.05
    assert field.log_likelihoods(poses, ranges, bearings) == pytest.approx(2 * np.log(pz), rel=1e-5)
    assert np.argmax(field.log_likelihoods(poses, ranges, bearings)) == np.argmax(
        field.weight_factors(poses, ranges, bearings)
    )
    assert np.array_equal(field.log_likelihoods(poses, np.zeros(0), np.zeros(0)), np.zeros(2))


def test_surfaces_only_scores_a_point_deep_in_a_solid_block_as_a_miss():
    """A 1 m thick outer wall: nav2's field calls every point inside it a perfect hit; the surface field
    measures the depth below the face that the free space sees."""
    grid = GridSpec.covering(np.array([0.0, 0.0]), np.array([4.0, 4.0]), 0.1, margin=0.0)
    gx, _ = grid.cell_centers()
    occupied = gx > 3.0  # solid from x = 3 to the map's edge
    occ = OccupancyGrid(grid, occupied, ~occupied)
    assert occ.surfaces().sum() == occupied[:, np.argmax(occupied[0])].sum()  # one column of cells: the face
    params = LikelihoodFieldParams(0.5, 0.5, 0.2, 2.0, 10.0)
    nav2 = LikelihoodField(occ, params)
    ours = LikelihoodField(occ, LikelihoodFieldParams(0.5, 0.5, 0.2, 2.0, 10.0, surfaces_only=True))
    face, deep = np.array([[3.05, 2.0]]), np.array([[3.85, 2.0]])
    assert nav2.distance_at(face)[0] == 0 and nav2.distance_at(deep)[0] == 0
    assert ours.distance_at(face)[0] == 0
    assert ours.distance_at(deep)[0] == pytest.approx(0.8)
    # In free space both fields agree: the face is the nearest occupied cell.
    free = np.array([[1.0, 1.0], [2.5, 3.0]])
    np.testing.assert_allclose(ours.distance_at(free), nav2.distance_at(free))
