import numpy as np
import pytest

from pimm_agents.particles.belief import read_belief
from pimm_agents.pimm.config import WallFieldConfig
from pimm_agents.pimm.feature_filter import FeatureFilter, FeatureFilterConfig
from pimm_agents.pimm.scan_features import OdometryHistory, compensate, wall_points
from pimm_env.geometry import carry, compose, wrap_angle
from pimm_env.world.semantics import SemanticClass
from tests.scenes import features_from, l_room, path, wall_field_for, walls_seen_from


def correct(
    filt: FeatureFilter,
    features: np.ndarray,
    suggestions: np.ndarray,
    previous: np.ndarray | None = None,
    wall_points: np.ndarray | None = None,
) -> np.ndarray | None:
    """The thesis filter's own measurement step: weigh, read the estimate, resample and inject."""
    filt.weigh(features, wall_points)
    estimate = filt.estimate(previous)
    filt.resample_and_inject(suggestions)
    return estimate


def run(filt: FeatureFilter, poses: np.ndarray, with_features: bool = True) -> np.ndarray | None:
    """Drive the filter along ``poses``; the final estimate (the last converged one carried by odometry)."""
    estimate = None
    for pose in poses:
        if filt.motion_update(pose):  # odometry = the true path (the odometry frame is the map frame here)
            found = correct(filt, features_from(pose) if with_features else np.zeros((0, 5)), np.zeros((0, 2)))
            if found is not None:
                estimate, at = found, pose
    return None if estimate is None else carry(estimate, at, poses[-1])


def make_filter(n: int = 3000, **overrides) -> FeatureFilter:
    occupancy, corners = l_room()
    filt = FeatureFilter(occupancy, corners, FeatureFilterConfig(num_particles=n, **overrides))
    filt.reset(np.random.default_rng(0))
    return filt


def test_converges_from_uniform_and_tracks():
    filt = make_filter()
    poses = path()
    run(filt, poses)
    estimate = filt.best_mean()
    assert np.hypot(*(estimate[:2] - poses[-1, :2])) < 0.3
    assert abs(np.degrees(estimate[2] - poses[-1, 2])) < 10
    near = np.hypot(*(filt.particles[:, :2] - poses[-1, :2]).T) < 0.5
    assert np.sum(filt.weights[near]) > 0.8


def test_the_estimate_is_the_heavier_mode_not_the_point_between_modes():
    # the best 100 particles split 60 / 40 between two poses 4 m apart: the thesis's plain mean lies between
    # them, in neither; ours is the heavier mode's mean
    filt = make_filter(n=1000)
    filt.particles[:] = [8.0, 1.0, 0.0]
    filt.particles[:60] = [2.0, 1.5, 0.3]
    filt.particles[60:100] = [2.0, 5.5, 0.3]
    filt.weights[:] = 1e-6
    filt.weights[:100] = 1.0
    filt.weights /= filt.weights.sum()
    assert np.allclose(filt.best_mean(), [2.0, 1.5, 0.3])
    filt.config = FeatureFilterConfig(num_particles=1000, thesis=True)  # the mean of all the heaviest
    assert np.allclose(filt.best_mean(), [2.0, 3.1, 0.3])
    with pytest.raises(ValueError, match="estimate_num_particles"):
        FeatureFilterConfig(estimate_num_particles=0)


def test_no_features_keeps_weights_normalized_and_finite():
    filt = make_filter(n=500)
    run(filt, path()[:20], with_features=False)
    assert np.isfinite(filt.particles).all() and np.isfinite(filt.weights).all()
    assert filt.weights.sum() == pytest.approx(1.0)
    assert np.isfinite(filt.best_mean()).all()


def test_occupied_cells_lose_weight():
    filt = make_filter(n=1000)
    filt.particles[:500, :2] = [6.1, 4.5]  # inside the missing block: not free
    filt.measurement_update(np.zeros((0, 5)))
    assert filt.weights[:500].sum() == pytest.approx(0.1 / 1.1)


def test_injection_puts_particles_around_the_suggestions():
    filt = make_filter(n=2000)
    suggestion = np.array([[2.0, 4.0]])
    replaced = filt.inject(suggestion)
    assert len(replaced) == 100
    near = np.hypot(*(filt.particles[replaced, :2] - suggestion[0]).T) < 1.5  # 3 sigma
    assert near.sum() >= 50  # half go to the suggestion (a few of the uniform ones may land near it too)
    assert filt.weights.sum() == pytest.approx(1.0)


def test_latency_compensation_removes_the_lag_of_a_delayed_feature():
    filt = make_filter(n=2)
    at_scan = np.array([2.0, 1.5, 0.0])
    now = np.array([2.6, 1.5, 0.2])  # the robot drove on while the scan was processed
    filt.particles = np.array([now, at_scan])
    features = features_from(at_scan, reach=20.0)
    # odometry frame rotated and shifted from the map frame: only relative odometry may matter
    odom_frame = np.array([5.0, -3.0, 1.0])
    odom_scan, odom_now = compose(odom_frame, at_scan)[0], compose(odom_frame, now)[0]
    compensated = filt.likelihoods(compensate(features, odom_scan, odom_now))
    raw = filt.likelihoods(features)
    assert compensated[0] > compensated[1]  # the particle at the true current pose wins
    assert raw[1] > raw[0]  # without compensation the lagging pose wins
    expected = features_from(now, reach=20.0)[:, :3]
    assert np.allclose(compensate(features, odom_scan, odom_now)[:, :3], expected, atol=1e-9)


def test_odometry_history_interpolates():
    history = OdometryHistory(span_s=1.0)
    history.add(0.0, np.array([0.0, 0.0, 0.0]))
    history.add(0.2, np.array([1.0, 0.0, 0.0]))
    assert history.at(0.1) == pytest.approx([0.5, 0.0, 0.0])
    assert history.at(5.0) == pytest.approx([1.0, 0.0, 0.0])
    history.add(1.5, np.array([2.0, 0.0, 0.0]))  # older than the span: forgotten
    assert history.at(0.0) == pytest.approx([2.0, 0.0, 0.0])


def test_bad_settings_and_features_are_named():
    with pytest.raises(ValueError, match="alpha"):
        FeatureFilterConfig(alpha=0.0)
    filt = make_filter(n=10)
    with pytest.raises(ValueError, match="sigma"):
        filt.measurement_update(np.array([[1.0, 1.0, 0.0, 0.0, 0.1]]))
    with pytest.raises(ValueError, match="finite"):
        filt.measurement_update(np.array([[np.nan, 1.0, 0.0, 0.1, 0.1]]))


def test_a_heavier_few_elsewhere_do_not_move_a_held_estimate():
    """The 100 heaviest particles sit in a look-alike place, but most of the weight is at the held pose."""
    filt = make_filter(n=1000, replace_worst_fraction=0.0)
    held, elsewhere = np.array([2.0, 1.5, 0.0]), np.array([8.0, 1.5, 0.0])
    filt.particles = np.vstack(
        [np.tile(held, (200, 1)), np.tile(elsewhere, (100, 1)), np.tile([4.0, 4.0, 1.0], (700, 1))]
    )
    filt.weights = np.concatenate([np.full(200, 3.0), np.full(100, 5.0), np.full(700, 1e-3)])
    filt.weights /= filt.weights.sum()
    weights = filt.weights.copy()
    assert np.allclose(correct(filt, np.zeros((0, 5)), np.zeros((0, 2)))[:2], elsewhere[:2]), "no held pose: moves"
    filt.particles[:] = np.vstack(
        [np.tile(held, (200, 1)), np.tile(elsewhere, (100, 1)), np.tile([4.0, 4.0, 1.0], (700, 1))]
    )
    filt.weights = weights.copy()
    assert correct(filt, np.zeros((0, 5)), np.zeros((0, 2)), previous=held) is None, "the held pose weighs more"
    filt.particles[:] = np.vstack(
        [np.tile(held, (200, 1)), np.tile(elsewhere, (100, 1)), np.tile([4.0, 4.0, 1.0], (700, 1))]
    )
    filt.weights = np.concatenate([np.full(200, 1.0), np.full(100, 5.0), np.full(700, 1e-3)])
    filt.weights /= filt.weights.sum()
    assert np.allclose(correct(filt, np.zeros((0, 5)), np.zeros((0, 2)), previous=held)[:2], elsewhere[:2])


def test_wall_points_alone_find_and_hold_the_pose():
    """No corners at all (a corridor's case): the scan's walls against the occupancy map still localize."""
    occupancy, corners = l_room()
    config = FeatureFilterConfig(num_particles=3000)
    filt = FeatureFilter(occupancy, corners, config, wall_field_for(occupancy), 0.2)
    filt.reset(np.random.default_rng(0))
    poses = path()
    for pose in poses:
        if filt.motion_update(pose):
            correct(filt, np.zeros((0, 5)), np.zeros((0, 2)), wall_points=walls_seen_from(pose))
    estimate = filt.best_mean()
    assert np.hypot(*(estimate[:2] - poses[-1, :2])) < 0.3
    assert abs(np.degrees(wrap_angle(estimate[2] - poses[-1, 2]))) < 10


def test_nothing_measured_replaces_no_particle():
    """With no features and no wall points the weights say nothing about which particles are worst: injecting
    then would wear away a tracked cluster by 5 % a step."""
    filt = make_filter(n=1000)
    before = filt.particles.copy()
    correct(filt, np.zeros((0, 5)), np.array([[2.0, 4.0]]))
    assert not filt.informed
    assert np.array_equal(filt.particles, before)
    correct(filt, features_from(np.array([2.0, 1.5, 0.0])), np.array([[2.0, 4.0]]))
    assert filt.informed
    assert np.count_nonzero(np.any(filt.particles != before, axis=1)) >= 45  # 5 %, some replaced by a look-alike


def test_wall_points_are_the_wall_band_spread_over_bearings():
    angles = np.linspace(-np.pi, np.pi, 40, endpoint=False)
    cloud = np.column_stack([3 * np.cos(angles), 3 * np.sin(angles), np.zeros(40)])
    cloud[::2, 2] = 1.8  # above the band (a lintel height): never used
    labels = np.full(40, int(SemanticClass.WALL))
    labels[1::4] = int(SemanticClass.CLUTTER)
    points = wall_points(cloud, labels, 4)
    assert points.shape == (4, 2)
    kept = np.arange(40)[(cloud[:, 2] < 1.0) & (labels == int(SemanticClass.WALL))]
    assert all(np.any(np.all(np.isclose(cloud[kept, :2], p), axis=1)) for p in points)
    bearings = np.sort(np.arctan2(points[:, 1], points[:, 0]))
    assert np.min(np.diff(bearings)) > np.pi / 4  # spread round the scan, not bunched
    with pytest.raises(ValueError, match="wall_field.points"):
        WallFieldConfig(points=0)


def test_adaptive_set_shrinks_once_converged_and_finds_a_kidnapped_robot():
    filt = make_filter(6000, min_particles=500)
    east = np.array([[x, 1.5, 0.0] for x in np.arange(1.0, 8.0, 0.15)])
    sizes = []
    for pose in east:
        if filt.motion_update(pose):
            correct(filt, features_from(pose), np.zeros((0, 2)))
            sizes.append(len(filt.particles))
    assert max(sizes) <= 6000 and min(sizes) >= 500 and sizes[-1] < 1500  # a tight cluster: KLD's few, + injected
    assert np.hypot(*(filt.best_mean()[:2] - east[-1, :2])) < 0.3
    # kidnapped to the west wing: the odometry drives on east at y = 1.5, the robot east at y = 4.5 from x = 1
    estimate = None
    for step, odom in enumerate(np.array([[x, 1.5, 0.0] for x in np.arange(8.0, 12.5, 0.15)])):
        truth = np.array([1.0 + 0.15 * step, 4.5, 0.0])
        if filt.motion_update(odom):
            found = correct(filt, features_from(truth), truth[None, :2])  # the fingerprints point at the truth
            if found is not None:
                estimate, at = found, odom
    assert estimate is not None
    assert np.hypot(*(carry(estimate, at, odom)[:2] - truth[:2])) < 0.5
    assert len(filt.particles) < 6000


def test_adaptive_injection_joins_a_small_set_and_replaces_in_a_full_one():
    filt = make_filter(2000, min_particles=100)
    filt.particles, filt.weights = filt.particles[:300], np.full(300, 1 / 300)
    added = filt.inject(np.array([[2.0, 2.0]]))
    assert len(filt.particles) == 400 and list(added) == list(range(300, 400))  # 5 % of 2000 joined
    assert filt.weights.sum() == pytest.approx(1.0)
    full = make_filter(2000, min_particles=100)
    full.inject(np.array([[2.0, 2.0]]))
    assert len(full.particles) == 2000
    with pytest.raises(ValueError, match="min_particles must be at least 1, got 0"):
        FeatureFilterConfig(num_particles=100, min_particles=0)


def test_per_mode_budgets_keep_a_light_twin_alive_with_its_weight():
    filt = make_filter(2000)
    rng = np.random.default_rng(4)
    filt.particles = np.vstack(
        [
            np.array([2.0, 1.5, 0.0]) + rng.normal(0, 0.05, (1900, 3)),
            np.array([2.0, 4.5, 0]) + rng.normal(0, 0.05, (100, 3)),
        ]
    )
    filt.weights = np.concatenate([np.full(1900, 0.98 / 1900), np.full(100, 0.02 / 100)])
    filt.ess = 1.0  # degenerate: resample now
    filt.belief = read_belief(filt.particles, filt.weights)
    assert filt.resample_if_degenerate()
    twin = filt.particles[:, 1] > 3
    # the twin keeps its 2 % of the belief and mode_min_particles particles (its share alone would be 40)
    assert twin.sum() == 100 and filt.weights[twin].sum() == pytest.approx(0.02)
    plain = make_filter(2000, thesis=True)  # resampled as one set
    plain.particles, plain.weights, plain.ess = filt.particles.copy(), filt.weights.copy(), 1.0
    plain.weights = np.where(twin, 0.02 / twin.sum(), 0.98 / (~twin).sum())
    plain.resample_if_degenerate()
    assert (plain.particles[:, 1] > 3).sum() < 80
