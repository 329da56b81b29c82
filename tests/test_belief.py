import numpy as np
import pytest

from pimm_agents.particles.belief import (
    BeliefConfig,
    Confirmation,
    belief_status,
    covariance_about,
    hypotheses_of,
    read_belief,
)
from pimm_agents.particles.kld import bin_indices
from pimm_agents.particles.pose_clusters import cluster_labels, cluster_statistics


def blob(rng: np.random.Generator, centre, n: int, spread: float = 0.1) -> np.ndarray:
    poses = np.tile(np.asarray(centre, dtype=float), (n, 1))
    poses[:, :2] += rng.normal(0, spread, (n, 2))
    poses[:, 2] += rng.normal(0, 0.02, n)
    return poses


def test_two_places_of_like_weight_are_ambiguous_and_one_alone_is_localized():
    rng = np.random.default_rng(0)
    poses = np.vstack([blob(rng, [1, 1, 0], 500), blob(rng, [9, 1, 0], 500)])
    config = BeliefConfig()
    belief = read_belief(poses, np.full(1000, 1e-3))
    assert len(belief.modes) == 2 and belief_status(belief, 0, config) == "ambiguous"
    hypotheses = hypotheses_of(belief, 3)
    assert len(hypotheses) == 2 and {round(h.x) for h in hypotheses} == {1, 9}
    assert sum(h.weight for h in hypotheses) == pytest.approx(1.0)
    # the evidence moves 97 % of the weight to the place at x = 9: one place, localized
    weights = np.where(poses[:, 0] > 5, 0.97 / 500, 0.03 / 500)
    belief = read_belief(poses, weights)
    assert belief.modes[0].mean[0] == pytest.approx(9, abs=0.05)
    assert belief_status(belief, 0, config) == "localized"
    assert belief_status(belief, 1, config) == "lost"  # an estimate in the light mode holds 3 % of the belief


def test_a_cloud_still_searching_is_lost():
    rng = np.random.default_rng(1)
    poses = np.column_stack([rng.uniform(0, 20, 3000), rng.uniform(0, 10, 3000), rng.uniform(-np.pi, np.pi, 3000)])
    belief = read_belief(poses, np.full(3000, 1 / 3000))
    assert belief_status(belief, 0, BeliefConfig()) == "lost"


def test_cluster_statistics_match_a_direct_computation():
    rng = np.random.default_rng(2)
    poses = np.vstack([blob(rng, [0, 0, 3.1], 200, 0.2), blob(rng, [5, 5, 1.0], 100, 0.1)])
    weights = rng.uniform(0.5, 1.5, 300)
    weights /= weights.sum()
    labels = cluster_labels(poses, 0.5, np.radians(10))
    clusters = cluster_statistics(poses, weights, labels)
    first = poses[:200]
    w = weights[:200] / weights[:200].sum()
    mean = w @ first[:, :2]
    assert clusters[0].weight == pytest.approx(weights[:200].sum())
    np.testing.assert_allclose(clusters[0].mean[:2], mean)
    np.testing.assert_allclose(
        clusters[0].covariance[:2, :2], ((first[:, :2] - mean) * w[:, None]).T @ (first[:, :2] - mean)
    )
    assert abs(np.angle(np.exp(1j * (clusters[0].mean[2] - 3.1)))) < 0.01  # theta's mean across the wrap


def scipy_cluster_labels(poses: np.ndarray, xy_size: float, theta_size: float) -> np.ndarray:
    """The labelling the compiled flood fill replaced: ndimage's 26-neighbourhood labels on the bins, theta's
    first plane copied past its last, the copies' labels joined."""
    from scipy import ndimage
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    ix, iy, it, n_theta = bin_indices(poses, xy_size, theta_size)
    ix, iy = ix - ix.min(), iy - iy.min()
    occupied = np.zeros((ix.max() + 1, iy.max() + 1, n_theta + 1), dtype=bool)
    occupied[ix, iy, it] = True
    occupied[:, :, n_theta] = occupied[:, :, 0]
    labels, count = ndimage.label(occupied, structure=np.ones((3, 3, 3), dtype=bool))
    first, copy = labels[:, :, 0].ravel(), labels[:, :, n_theta].ravel()
    pairs = (first > 0) & (copy > 0)
    graph = coo_matrix((np.ones(pairs.sum()), (first[pairs], copy[pairs])), shape=(count + 1, count + 1))
    _, merged = connected_components(graph, directed=False)
    return np.unique(merged[labels[ix, iy, it]], return_inverse=True)[1]


@pytest.mark.parametrize("seed", range(6))
def test_cluster_labels_number_clusters_as_ndimage_does(seed):
    """Clouds spread, clumped and wrapped in heading: the same labels, numbered alike, as the scipy labelling."""
    rng = np.random.default_rng(seed)
    spread = [20.0, 3.0, 1.0, 0.3, 8.0, 0.05][seed]
    n = [10_000, 3000, 500, 200, 40, 1][seed]
    poses = np.column_stack([rng.normal(0, spread, (n, 2)), rng.uniform(-np.pi, np.pi, n)])
    if seed == 3:  # a blob across theta's wrap, joined only through it
        poses[:, 2] = np.where(rng.random(n) < 0.5, np.pi - 0.02, -np.pi + 0.02)
    for bins in ((0.5, np.radians(10.0)), (0.25, np.radians(5.0)), (1.0, np.radians(90.0))):
        np.testing.assert_array_equal(cluster_labels(poses, *bins), scipy_cluster_labels(poses, *bins))
    assert cluster_labels(poses[:0], 0.5, 0.2).shape == (0,)


def test_covariance_about_an_offset_estimate_grows_by_the_offset():
    rng = np.random.default_rng(3)
    poses = blob(rng, [2, 2, 0], 400)
    belief = read_belief(poses, np.full(400, 1 / 400))
    cov = covariance_about(belief.modes[0], belief.modes[0].mean + np.array([0.3, 0, 0]))
    assert cov[0, 0] == pytest.approx(belief.modes[0].covariance[0, 0] + 0.09)


def test_confirmation_holds_localized_back_and_restarts_after_a_jump():
    confirm = Confirmation(3)
    assert [confirm("localized", False) for _ in range(4)] == ["ambiguous", "ambiguous", "localized", "localized"]
    assert confirm("localized", True) == "ambiguous"  # the estimate moved to another place
    assert confirm("lost", False) == "lost" and confirm.streak == 0


def test_a_switch_counts_the_updates_its_rival_led():
    confirm = Confirmation(10)
    assert confirm("localized", True, earned=10) == "localized" and confirm.streak == 11
    assert confirm("localized", True) == "ambiguous" and confirm.streak == 1


def test_bad_settings_are_named():
    with pytest.raises(ValueError, match="localized_min_weight"):
        BeliefConfig(localized_min_weight=1.5)
    with pytest.raises(ValueError, match="confirm_updates"):
        BeliefConfig(confirm_updates=-1)
