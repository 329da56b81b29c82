"""PIMM's measurement step: the filter weighs, the ambiguity check reviews beside it, the step applies the decision."""

import numpy as np
import pytest

from pimm_agents.pimm.ambiguity import Decision
from pimm_agents.pimm.feature_filter import FeatureFilterConfig
from pimm_agents.pimm.rivals import RivalConfig
from tests.scenes import (
    CABINET,
    features_from,
    kidnapped_into_an_office,
    l_room,
    make_step,
    no_corners,
    office_row,
    path,
    rays_from,
    round_east_and_round,
    track,
    twin_rooms,
    walls_seen_from,
)


def walls_in(occupancy):
    return lambda pose: (np.zeros((0, 5)), rays_from(occupancy, pose, 10.0))


def test_twin_rooms_are_ambiguous_until_the_block_that_tells_them_apart_is_seen():
    occupancy = twin_rooms()
    step = make_step(occupancy, no_corners(), FeatureFilterConfig(num_particles=10_000))
    step.filter.reset(np.random.default_rng(0))
    truth = round_east_and_round()
    updates = track(step, truth, truth, walls_in(occupancy))
    # the block is in sight through the door from x = 15.6 on
    before = [status for status, _, pose in updates if pose[0] < 15.5]
    assert "localized" not in before and before[-20:] == ["ambiguous"] * 20
    twins = step.reading.hypotheses
    assert updates[-1][0] == "localized" and np.hypot(*(updates[-1][1][:2] - truth[-1, :2])) < 0.3
    assert twins[0].x > 12 and (len(twins) == 1 or twins[1].weight < 0.1 * twins[0].weight)


def test_kidnapped_into_one_of_a_row_of_identical_offices_it_is_never_localized_until_the_cabinet_is_seen():
    occupancy = office_row()
    step = make_step(occupancy, no_corners(), FeatureFilterConfig(num_particles=5000))
    step.filter.reset(np.random.default_rng(0))
    odometry, truth, _ = kidnapped_into_an_office()
    updates = track(step, odometry, truth, walls_in(occupancy))

    def sees_the_cabinet(pose):
        c, s = np.cos(pose[2]), np.sin(pose[2])
        ends = pose[:2] + rays_from(occupancy, pose, 10.0) @ np.array([[c, s], [-s, c]])
        x0, x1, _, y1 = CABINET
        return bool(np.any((ends[:, 0] > x0 - 0.15) & (ends[:, 0] < x1 + 0.15) & (ends[:, 1] < y1 + 0.15)))

    carried = next(k for k, (_, _, pose) in enumerate(updates) if pose[1] > 2.2)  # the first update in the office
    after = [(status, pose) for status, _, pose in updates[carried:]]
    first_sight = next(k for k, (_, pose) in enumerate(after) if sees_the_cabinet(pose))
    assert updates[carried - 1][0] == "localized"  # right, in the corridor, before the kidnap
    assert "localized" not in [status for status, _ in after[:first_sight]]
    assert "ambiguous" in [status for status, _ in after[:first_sight]]
    status, estimate, pose = updates[-1]
    assert status == "localized" and np.hypot(*(estimate[:2] - pose[:2])) < 0.3


def test_a_kidnap_turns_localized_off_within_a_few_updates():
    occupancy, corners = l_room()
    step = make_step(occupancy, corners, FeatureFilterConfig(num_particles=3000))
    step.filter.reset(np.random.default_rng(0))
    # east along y = 1.5, then the robot is carried to the east wing's far end, facing west, while the odometry
    # goes on east: its scans are then the east wing's
    odometry = np.array([[x, 1.5, 0.0] for x in np.arange(1.0, 9.0, 0.15)])
    carried = np.array([[9.5 - 0.15 * k, 1.5, np.pi] for k in range(len(odometry))])
    truths = np.where((odometry[:, 0] < 6.0)[:, None], odometry, carried)
    updates = track(step, odometry, truths, lambda pose: (features_from(pose), walls_seen_from(pose)))
    kidnap = int(np.argmax(odometry[1:, 0] >= 6.0))
    assert updates[kidnap - 1][0] == "localized"
    assert "localized" not in [status for status, _, _ in updates[kidnap + 1 : kidnap + 4]]  # the first may hold it


def test_the_reported_covariance_is_consistent_with_the_error_on_a_tracked_run():
    occupancy, corners = l_room()
    step = make_step(occupancy, corners, FeatureFilterConfig(num_particles=3000))
    step.filter.reset(np.random.default_rng(1))
    inside, traces = [], []
    poses = path()
    for status, estimate, pose in track(step, poses, poses, lambda p: (features_from(p), walls_seen_from(p))):
        if status == "localized":
            error, cov = estimate[:2] - pose[:2], step.reading.covariance[:2, :2]
            inside.append(error @ np.linalg.solve(cov, error) <= 9.0)
            traces.append(np.trace(cov))
    assert len(inside) > 20 and np.mean(inside) >= 0.9
    assert max(traces) < 0.5  # the estimate's mode, not the whole particle set (the L room: ~8 m^2)


def test_no_place_is_localized_before_the_rival_check_has_kept_settle_scans():
    occupancy, corners = l_room()
    poses = path()
    first = {}
    for settle in (0, 25):
        step = make_step(occupancy, corners, FeatureFilterConfig(num_particles=3000), RivalConfig(settle_scans=settle))
        step.filter.reset(np.random.default_rng(0))
        statuses = [s for s, _, _ in track(step, poses, poses, lambda p: (features_from(p), walls_seen_from(p)))]
        first[settle] = statuses.index("localized")
    # without it the first claim comes once 10 updates confirm it; with it, not before 25 scans are kept
    assert first[0] < 25 <= first[25]


def localized_in_the_second_room(rivals: RivalConfig | None = RivalConfig()):
    """A step driven round and east in the twin rooms until the block has told them apart: localized, right."""
    occupancy = twin_rooms()
    step = make_step(occupancy, no_corners(), FeatureFilterConfig(num_particles=10_000), rivals)
    step.filter.reset(np.random.default_rng(0))
    truth = round_east_and_round()
    status, held, now = track(step, truth, truth, walls_in(occupancy))[-1]
    assert status == "localized" and np.hypot(*(held[:2] - now[:2])) < 0.3
    return step, held


def weight_moved_to_the_twin(step, held: np.ndarray) -> np.ndarray:
    """The filter's weight goes over to the twin in the first room (as phantom features would take it)."""
    filt, twin = step.filter, held - [12.0, 0.0, 0.0]
    filt.particles[:100], filt.particles[100:200] = twin, held
    filt.weights = np.full(len(filt.particles), 1e-9)
    filt.weights[:100], filt.weights[100:200] = 0.6 / 100, 0.4 / 100
    filt.weights /= filt.weights.sum()
    return twin


def test_a_hold_decision_keeps_the_estimate_and_moves_the_twins_particles_onto_it():
    step, held = localized_in_the_second_room()
    weight_moved_to_the_twin(step, held)
    found = step(np.zeros((0, 5)), None, np.zeros((0, 2)), held, held)  # nothing measured: the weights stand
    assert found is None, "the held place stays: the kept scans rule the twin out"
    assert np.hypot(*(step.filter.particles[:100, :2] - held[:2]).T).max() < 1e-9, "the twin's particles moved"
    assert step.reading.status == "localized"  # offered to the rival check, which the kept scans rule out


def test_with_the_check_off_the_filter_jumps_to_the_twin():
    step, held = localized_in_the_second_room(rivals=None)
    twin = weight_moved_to_the_twin(step, held)
    found = step(np.zeros((0, 5)), None, np.zeros((0, 2)), held, held)
    assert found is not None and np.hypot(*(found[:2] - twin[:2])) < 0.1


def test_a_held_estimate_stays_for_at_most_switch_updates_refusals_until_it_is_localized_again():
    occupancy = twin_rooms()
    step = make_step(occupancy, no_corners(), FeatureFilterConfig(num_particles=1000))
    check = step.check
    assert check is not None
    held, twin = np.array([14.0, 1.0, 0.0]), np.array([2.0, 1.0, 0.0])
    check.tracker.holds = lambda *_: True  # the kept scans always favour the held place
    check.after("localized", False)
    limit = check.tracker.config.switch_updates
    answers = []
    for _ in range(limit + 2):
        answers.append(check.holds(held, twin, np.zeros(3), None))
        check.after("ambiguous", False)
    assert answers == [True] * limit + [False, False]  # a kidnap to a look-alike place is not held forever
    check.after("localized", False)  # confirmed again: the count starts anew
    assert check.holds(held, twin, np.zeros(3), None)


class MovingCheck:
    """A check that always decides to move the estimate to ``target``: what the step does with such a decision."""

    def __init__(self, target: np.ndarray) -> None:
        self.target, self.reported = target, []

    def reset(self) -> None: ...

    def holds(self, *_) -> bool:
        return False

    def review(self, view, odom, pose, reading, reported, walls, left, suggestions) -> Decision:
        return Decision("ambiguous", (), self.target, RivalConfig().switch_updates)

    def after(self, status: str, jumped: bool) -> None:
        self.reported.append((status, jumped))


def test_a_move_decision_moves_the_estimates_mode_and_reports_ambiguous():
    occupancy, corners = l_room()
    step = make_step(occupancy, corners, FeatureFilterConfig(num_particles=2000), rivals=None)
    start, pose, target = np.array([2.0, 1.5, 0.0]), np.array([2.2, 1.5, 0.0]), np.array([8.0, 1.5, np.pi / 2])
    step.filter.reset(np.random.default_rng(0), start, np.diag([0.01, 0.01, 0.001]))
    step.check = MovingCheck(target)  # type: ignore[assignment]
    step.filter.motion_update(start)
    assert step.filter.motion_update(pose)
    found = step(features_from(pose), None, np.zeros((0, 2)), pose, pose)
    assert found is not None and np.allclose(found, target)
    assert step.reading.status == "ambiguous" and step.check.reported == [("ambiguous", True)]
    near = np.hypot(*(step.filter.particles[:, :2] - target[:2]).T) < 0.5
    assert near.mean() > 0.9  # the mode's particles went with the estimate


def test_the_check_switched_off_leaves_the_thesis_filters_results():
    """The step without a check is the filter's own weigh, estimate, resample and inject, draw for draw."""
    occupancy, corners = l_room()
    config = FeatureFilterConfig(num_particles=2000)
    step = make_step(occupancy, corners, config, rivals=None)
    bare = make_step(occupancy, corners, config, rivals=None).filter
    step.filter.reset(np.random.default_rng(3))
    bare.reset(np.random.default_rng(3))
    previous = None
    for pose in path():
        moved = step.filter.motion_update(pose)
        assert bare.motion_update(pose) == moved
        if moved:
            features, walls = features_from(pose), walls_seen_from(pose)
            found = step(features, walls, pose[None, :2], previous, pose)
            bare.weigh(features, walls)
            expected = bare.estimate(previous)
            bare.resample_and_inject(pose[None, :2])
            assert (found is None) == (expected is None) and (found is None or np.array_equal(found, expected))
            assert np.array_equal(step.filter.particles, bare.particles)
            previous = found if found is not None else previous
    assert step.reading.status == "localized"


@pytest.mark.parametrize("settle", [0, 10])
def test_a_lost_reading_passes_the_check_unchanged(settle):
    occupancy, corners = l_room()
    step = make_step(occupancy, corners, FeatureFilterConfig(num_particles=500), RivalConfig(settle_scans=settle))
    step.filter.reset(np.random.default_rng(0))
    step.filter.motion_update(np.zeros(3))
    step.filter.motion_update(np.array([0.2, 0.0, 0.0]))
    assert step(np.zeros((0, 5)), None, np.zeros((0, 2)), None, np.array([0.2, 0.0, 0.0])) is None
    assert step.reading.status == "lost"
