import numpy as np
import pytest

from pimm_agents.particles.kld import bin_keys, kld_bound, kld_limit, kld_sample_count


@pytest.mark.parametrize(("k", "expected"), [(2, 19.2731), (10, 130.1616), (100, 1128.6504)])
def test_fox_bound_matches_hand_computed_values(k, expected):
    # (k-1)/(2*0.05) * (1 - 2/(9(k-1)) + sqrt(2/(9(k-1))) * 0.99)^3, worked out by hand.
    assert kld_bound(k, 0.05, 0.99) == np.ceil(expected)


def test_limit_is_clamped_and_maximal_for_one_bin():
    assert kld_limit(1, 0.05, 0.99, 500, 2000) == 2000
    assert kld_limit(2, 0.05, 0.99, 500, 2000) == 500
    assert kld_limit(100, 0.05, 0.99, 500, 2000) == 1129
    assert kld_limit(10_000, 0.05, 0.99, 500, 2000) == 2000


def test_bins_wrap_in_theta_and_split_in_space():
    keys = bin_keys(
        np.array([[0.1, 0.1, np.pi - 0.01], [0.2, 0.4, -np.pi + 0.01 - 2 * np.pi], [0.6, 0.1, 0.0]]),
        0.5,
        np.radians(10),
    )
    assert keys[0] != keys[2]
    # pi - 0.01 and -pi + 0.01 are 0.02 rad apart but in the last and first bins of the circle
    assert keys[0] != keys[1]
    same = bin_keys(np.array([[0.1, 0.1, 0.01], [0.2, 0.3, 0.01 + 2 * np.pi]]), 0.5, np.radians(10))
    assert same[0] == same[1]


def test_sample_count_stops_once_the_bound_for_the_bins_so_far_is_exceeded():
    one_bin = np.zeros(2000, dtype=np.int64)
    assert kld_sample_count(one_bin, 0.05, 0.99, 500, 2000) == 2000
    # ten bins, visited in turn: once all are seen the limit is ceil(130.16) = 131, so the 132nd draw stops it
    ten_bins = np.arange(2000, dtype=np.int64) % 10
    assert kld_sample_count(ten_bins, 0.05, 0.99, 10, 2000) == 132
    assert kld_sample_count(ten_bins, 0.05, 0.99, 500, 2000) == 501  # min_particles wins
    # a new bin with every draw: the bound always stays ahead of the count
    assert kld_sample_count(np.arange(3000, dtype=np.int64), 0.05, 0.99, 10, 3000) == 3000


def test_compiled_bins_equal_the_numpy_expression():
    """Random poses far and near, and headings on the wrap's edges: the same bins as floor and NumPy's mod."""
    from pimm_agents.particles.kld import bin_indices

    rng = np.random.default_rng(0)
    poses = np.column_stack([rng.normal(0, 50, (20_000, 2)), rng.uniform(-20, 20, 20_000)])
    edges = [
        0.0,
        -0.0,
        np.pi,
        -np.pi,
        2 * np.pi,
        -2 * np.pi,
        np.nextafter(-np.pi, 0),
        np.nextafter(np.pi, 4),
        1e-300,
        -1e-300,
    ]
    poses[: len(edges), 2] = edges
    poses[: len(edges), :2] = [[0.5, -0.5]] * len(edges)
    for xy, theta in ((0.5, np.radians(10)), (0.25, np.radians(7)), (1.0, 1.0)):
        ix, iy, it, n_theta = bin_indices(poses, xy, theta)
        assert n_theta == int(np.ceil(2 * np.pi / theta))
        np.testing.assert_array_equal(ix, np.floor(poses[:, 0] / xy).astype(np.int64))
        np.testing.assert_array_equal(iy, np.floor(poses[:, 1] / xy).astype(np.int64))
        expected = np.floor(np.mod(poses[:, 2], 2 * np.pi) / theta).astype(np.int64) % n_theta
        np.testing.assert_array_equal(it, expected)
