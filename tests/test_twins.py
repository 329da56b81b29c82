import numpy as np
import pytest
from scipy import ndimage

import pimm_agents.pimm.ambiguity as ambiguity
import pimm_agents.pimm.kept_scans as kept_scans
from pimm_agents.corners.lookup import NearestCornerGrid
from pimm_agents.pimm.feature_filter import FeatureFilterConfig
from pimm_env.errors import LocalizerError, ParamsError
from pimm_env.geometry import carry, wrap_angle
from pimm_env.mapping.corner_map import CornerMap
from pimm_env.mapping.occupancy import OccupancyGrid
from pimm_env.mapping.twins import MapTwins, TwinConfig, local_peaks
from pimm_env.world.grid import GridSpec
from tests.scenes import make_step, rays_from, track, twin_rooms


def turned_rooms() -> OccupancyGrid:
    """Two 8 x 5 m rooms 12 m apart, each with a 1.5 x 1 m alcove: the second is the first turned half a turn."""
    grid = GridSpec.covering(np.array([0.0, 0.0]), np.array([20.0, 5.0]), 0.1, margin=0.5)
    gx, gy = grid.cell_centers()
    first = (gx > 0) & (gx < 8) & (gy > 0) & (gy < 5) & ~((gx > 6.5) & (gy > 4))
    second = (gx > 12) & (gx < 20) & (gy > 0) & (gy < 5) & ~((gx < 13.5) & (gy < 1))
    free = first | second
    return OccupancyGrid(grid, occupied=~free, free=free)


def near(poses: np.ndarray, pose: np.ndarray, metres: float = 0.4, degrees: float = 6.0) -> bool:
    return bool(
        np.any(
            (np.hypot(poses[:, 0] - pose[0], poses[:, 1] - pose[1]) < metres)
            & (np.abs(wrap_angle(poses[:, 2] - pose[2])) < np.radians(degrees))
        )
    )


def test_the_same_room_further_on_is_a_twin():
    twins = MapTwins(twin_rooms(), TwinConfig())
    found = twins.of(np.array([2.0, 1.0, 0.3]))
    assert near(found, np.array([14.0, 1.0, 0.3]))
    assert not near(found, np.array([2.0, 1.0, 0.3]), metres=1.4)  # not the place itself


def test_a_room_turned_half_a_turn_gives_a_turned_twin():
    twins = MapTwins(turned_rooms(), TwinConfig())
    pose = np.array([2.0, 1.5, 0.5])
    # the first room's (x, y) is the second's (20 - x, 5 - y), facing the other way
    assert near(twins.of(pose), np.array([18.0, 3.5, 0.5 + np.pi]))


def test_twins_are_carried_to_every_pose_of_a_cell():
    twins = MapTwins(twin_rooms(), TwinConfig())
    a, b = twins.of(np.array([2.1, 1.1, 0.0])), twins.of(np.array([2.8, 1.7, 1.0]))
    turn = a[:, 2]  # each twin turns the place by its own angle, the offset within the cell with it
    offsets = np.column_stack([np.cos(turn) * 0.7 - np.sin(turn) * 0.6, np.sin(turn) * 0.7 + np.cos(turn) * 0.6])
    assert len(a) == len(b) > 0 and np.allclose(b[:, :2] - a[:, :2], offsets, atol=1e-9)
    assert np.allclose(wrap_angle(b[:, 2] - a[:, 2]), 1.0)


def test_the_table_of_twins_gives_what_working_them_out_gives_and_only_for_its_own_map(tmp_path, monkeypatch):
    rooms = twin_rooms()
    made = MapTwins(rooms, TwinConfig())
    assert made.precompute() == len(made.free_cells()) > 0
    path = made.save(tmp_path / "twins.npz")
    taken = MapTwins(rooms, TwinConfig())
    assert taken.load(path)

    def worked_out(*args):  # with the table, no update works a cell out
        raise AssertionError("a cell was worked out although the table has it")

    monkeypatch.setattr(taken, "_twins_at", worked_out)
    rng = np.random.default_rng(0)
    gx, gy = rooms.grid.cell_centers()
    free = rng.choice(np.flatnonzero(rooms.free), 30, replace=False)  # poses where a localizer may be
    for pose in np.column_stack([gx.ravel()[free], gy.ravel()[free], rng.uniform(-3, 3, 30)]):
        np.testing.assert_array_equal(taken.of(pose), made.of(pose))
    assert not MapTwins(rooms, TwinConfig(min_overlap=0.7)).load(path)  # other settings: not taken
    assert not MapTwins(turned_rooms(), TwinConfig()).load(path)  # another map: not taken


def test_a_place_that_sees_no_walls_has_no_twins():
    grid = GridSpec.covering(np.array([0.0, 0.0]), np.array([40.0, 40.0]), 0.1)
    gx, gy = grid.cell_centers()
    free = (gx > 0) & (gx < 40) & (gy > 0) & (gy < 40)
    twins = MapTwins(OccupancyGrid(grid, occupied=~free, free=free), TwinConfig())
    assert len(twins.of(np.array([20.0, 20.0, 0.0]))) == 0


def close_pairs(found: np.ndarray) -> list[tuple[int, int]]:
    """The pairs of twins less than 1.5 m apart."""
    return [
        (i, j)
        for i in range(len(found))
        for j in range(i + 1, len(found))
        if np.hypot(*(found[i, :2] - found[j, :2])) < 1.5
    ]


def test_a_match_facing_the_other_way_beside_another_is_kept_only_when_turns_count():
    # a 40 m corridor: from its middle, the walls within 8 m match every shift along it, facing either way
    grid = GridSpec.covering(np.array([0.0, 0.0]), np.array([40.0, 3.0]), 0.1, margin=0.5)
    gx, gy = grid.cell_centers()
    free = (gx > 0) & (gx < 40) & (gy > 0) & (gy < 3)
    corridor = OccupancyGrid(grid, occupied=~free, free=free)
    place = np.array([20.5, 1.5, 0.0])  # a cell's centre: the twins lie where their matches were found
    by_position = MapTwins(corridor, TwinConfig(max_twins=20)).of(place)
    assert len(by_position) and not close_pairs(by_position)  # one twin per 1.5 m, whichever way it faces
    by_turn = MapTwins(corridor, TwinConfig(max_twins=20, distinct_turn_deg=30.0)).of(place)
    pairs = close_pairs(by_turn)
    assert pairs and all(abs(wrap_angle(by_turn[i, 2] - by_turn[j, 2])) > np.radians(30.0) for i, j in pairs)


@pytest.mark.parametrize(
    "bad", [{"angle_step_deg": 7.0}, {"min_overlap": 0.0}, {"radius_m": 0.0}, {"distinct_turn_deg": 190.0}]
)
def test_bad_settings_are_named(bad):
    with pytest.raises(LocalizerError, match="twins"):
        TwinConfig(**bad)


def started_at_the_truth(injection: float = 0.05) -> list[tuple[str, np.ndarray, np.ndarray]]:
    """A filter that starts around the true pose in the second room (no particle in the first), driven as in
    the twin-rooms test: east through the door, the block in sight from x = 15.6, on to x = 21; ``injection``
    is the share of particles replaced at random places after each update (``replace_worst_fraction``)."""
    occupancy = twin_rooms()
    corners = NearestCornerGrid(CornerMap(xy=np.zeros((1, 2)), z=np.ones(1), theta=np.zeros(1)))
    step = make_step(occupancy, corners, FeatureFilterConfig(num_particles=2000, replace_worst_fraction=injection))
    turn = np.array([[14.0, 1.0, a] for a in np.linspace(0.0, 2 * np.pi, 40)])
    truth = np.vstack([turn, [[x, 1.0, 0.0] for x in np.arange(14.0, 21.0, 0.12)]])
    step.filter.reset(np.random.default_rng(0), truth[0], np.diag([0.1, 0.1, 0.01]))
    return track(step, truth, truth, lambda pose: (np.zeros((0, 5)), rays_from(occupancy, pose, 10.0)))


def test_a_twin_the_filter_never_held_keeps_the_place_ambiguous_until_the_block_is_seen(monkeypatch):
    with_twins = started_at_the_truth()
    before = [status for status, _, pose in with_twins if pose[0] < 15.5]
    assert "localized" not in before
    assert with_twins[-1][0] == "localized"
    # without the map's twins, and without the injection (whose random particles in the first room the check
    # can also fit there), nothing offers the first room, and the place is called localized before the block
    monkeypatch.setattr(MapTwins, "of", lambda self, pose: np.zeros((0, 3)))
    without = [status for status, _, pose in started_at_the_truth(injection=0.0) if pose[0] < 15.5]
    assert "localized" in without


def test_a_place_is_called_localized_only_once_every_twin_was_looked_at(monkeypatch):
    # turning on one spot, the twin search from its one cell ranks shifted near-copies above the other room: with
    # only the six best (the check's count before it queued them all) and looked for from that cell alone, the
    # place is called localized before the robot has moved (without the injection, whose random particles in the
    # other room the check can also fit there; the margins summed as they are, without the raster's allowance)
    monkeypatch.setattr(ambiguity, "TWINS_FROM_CELLS", 1)
    monkeypatch.setattr(kept_scans, "MAP_ERROR_CELLS", 0.0)
    every = [status for status, _, pose in started_at_the_truth(injection=0.0) if pose[0] < 15.5]
    assert "localized" not in every
    monkeypatch.setattr(ambiguity, "TwinConfig", lambda: TwinConfig(max_twins=6))
    six = [status for status, _, pose in started_at_the_truth(injection=0.0) if pose[0] < 15.5]
    assert "localized" in six


def test_the_rival_check_is_set_from_a_params_section_and_settings_that_go_together_are_checked_together():
    from pimm_agents.params import apply_params
    from pimm_agents.pimm.config import PimmConfig

    config = apply_params(PimmConfig(), {"rivals": {"log_ratio": 5.0, "settle_scans": 20}}, "pimm")
    assert config.rivals.log_ratio == 5.0 and config.rivals.settle_scans == 20
    with pytest.raises(ParamsError, match="drop_log_ratio.*log_ratio"):
        apply_params(PimmConfig(), {"rivals": {"log_ratio": 10.0}}, "pimm")
    with pytest.raises(ParamsError, match="history_scans.*settle_scans"):
        apply_params(PimmConfig(), {"rivals": {"history_scans": 20, "settle_scans": 30}}, "pimm")
    with pytest.raises(ParamsError, match="rivals.enabled needs pimm.wall_field.enabled"):
        apply_params(PimmConfig(), {"wall_field": {"enabled": False}}, "pimm")
    thesis = apply_params(PimmConfig(), {"wall_field": {"enabled": False}, "rivals": {"enabled": False}}, "pimm")
    assert not thesis.wall_field.enabled and not thesis.rivals.enabled


def started_in_the_wrong_room() -> list[tuple[str, np.ndarray, np.ndarray]]:
    """The twin-rooms drive with every particle about the first room's twin of the true pose (12 m west), and a
    turn on the spot at its end: the switch comes once 10 updates in a row favour the true place by ln 1000 (here
    at about x = 20; the block is in sight from 15.6), and a place switched to is called localized only after 20
    more scans."""
    occupancy = twin_rooms()
    corners = NearestCornerGrid(CornerMap(xy=np.zeros((1, 2)), z=np.ones(1), theta=np.zeros(1)))
    step = make_step(occupancy, corners, FeatureFilterConfig(num_particles=2000))
    turn = np.array([[14.0, 1.0, a] for a in np.linspace(0.0, 2 * np.pi, 40)])
    drive = [[x, 1.0, 0.0] for x in np.arange(14.0, 21.0, 0.12)]
    truth = np.vstack([turn, drive, [[21.0, 1.0, a] for a in np.linspace(0.0, 2 * np.pi, 40)[1:]]])
    step.filter.reset(np.random.default_rng(0), truth[0] - [12.0, 0.0, 0.0], np.diag([0.1, 0.1, 0.01]))
    return track(step, truth, truth, lambda pose: (np.zeros((0, 5)), rays_from(occupancy, pose, 10.0)))


def test_a_rival_the_scans_favour_decisively_takes_the_estimate():
    moved = started_in_the_wrong_room()
    status, estimate, truth = moved[-1]
    assert status == "localized" and np.hypot(*(estimate[:2] - truth[:2])) < 0.3
    # never localized in the wrong room on the way
    assert all(s != "localized" or np.hypot(*(e[:2] - t[:2])) < 1.0 for s, e, t in moved)


def test_a_place_reported_localized_is_not_moved_by_the_rival_check():
    """The wrong-room drive again, with the wrong place taken as held (as if it had been reported localized
    since its last jump): the true place stands as a rival, the estimate is not moved to it."""
    occupancy = twin_rooms()
    corners = NearestCornerGrid(CornerMap(xy=np.zeros((1, 2)), z=np.ones(1), theta=np.zeros(1)))
    step = make_step(occupancy, corners, FeatureFilterConfig(num_particles=2000))
    turn = np.array([[14.0, 1.0, a] for a in np.linspace(0.0, 2 * np.pi, 40)])
    truth = np.vstack([turn, [[x, 1.0, 0.0] for x in np.arange(14.0, 21.0, 0.12)]])
    step.filter.reset(np.random.default_rng(0), truth[0] - [12.0, 0.0, 0.0], np.diag([0.1, 0.1, 0.01]))
    estimate, at, updates = None, None, 0
    for odom in truth:
        if step.filter.motion_update(odom):
            previous = None if estimate is None else carry(estimate, at, odom)
            found = step(np.zeros((0, 5)), rays_from(occupancy, odom, 10.0), np.zeros((0, 2)), previous, odom)
            estimate, at = (found, odom) if found is not None else (previous, odom)
            updates += 1
            if updates == 3:
                step.check.held = True  # as if it had been reported localized since its last jump
    assert estimate is not None and np.hypot(*(estimate[:2] - (truth[-1, :2] - [12.0, 0.0]))) < 0.5
    assert step.reading.status != "localized"
    assert any(np.hypot(h.x - truth[-1, 0], h.y - truth[-1, 1]) < 0.5 for h in step.reading.hypotheses)


@pytest.mark.parametrize("seed", range(4))
def test_local_peaks_are_the_maximum_filters_peaks_to_the_cell(seed):
    rng = np.random.default_rng(seed)
    score = np.round(rng.random((37, 53)), 1)  # coarse values: plateaus of equal cells, at the edges too
    score[:3, :3] = 0.9  # a plateau in a corner
    expected = np.nonzero((score >= 0.6) & (score == ndimage.maximum_filter(score, size=5)))
    rows, cols = local_peaks(score, 0.6)
    assert np.array_equal(rows, expected[0]) and np.array_equal(cols, expected[1])
    assert all(len(a) == 0 for a in local_peaks(score, 1.5))


def test_world_prepare_writes_a_table_of_twins_the_localizer_takes_whatever_the_maps_origin(tmp_path):
    from pimm_agents.preparation.prepare import prepare_world
    from pimm_env.mapping.derived_maps import load_derived_maps
    from pimm_env.mapping.twins import world_twins
    from pimm_env.world.files import load_world

    x = y = 0.7  # the maps' grid starts at 0.30000000000000004, which occupancy.yaml gives back as 0.3
    boxes = {  # name: class, min, max (the room of the other tests, moved)
        "floor": ("floor", (-0.5, -0.5, -0.1), (6.5, 4.5, 0.0)),
        "ceiling": ("ceiling", (-0.5, -0.5, 3.0), (6.5, 4.5, 3.1)),
        "south": ("wall", (-0.2, -0.2, 0.0), (6.2, 0.0, 3.0)),
        "north": ("wall", (-0.2, 4.0, 0.0), (6.2, 4.2, 3.0)),
        "west": ("wall", (-0.2, 0.0, 0.0), (0.0, 4.0, 3.0)),
        "east": ("wall", (6.0, 0.0, 0.0), (6.2, 4.0, 3.0)),
        "cabinet": ("clutter", (1.0, 3.0, 0.0), (2.0, 4.0, 1.8)),
    }
    world = tmp_path / "odd" / "world.yaml"
    world.parent.mkdir()
    lines = [f"format: pimm-world/1\nname: odd\nfloor_z: 0.0\nareas:\n  room: [[{x}, {y}], [{x + 6}, {y}], "
             f"[{x + 6}, {y + 4}], [{x}, {y + 4}]]\nelements:"]  # fmt: skip
    for name, (kind, lo, hi) in boxes.items():
        low, high = [lo[0] + x, lo[1] + y, lo[2]], [hi[0] + x, hi[1] + y, hi[2]]
        lines.append(f"  - {{name: {name}, class: {kind}, box: {{min: {low}, max: {high}}}}}")
    world.write_text("\n".join(lines) + "\n")
    prepare_world(world, progress=False)
    loaded = load_world(world)
    _, stale = world_twins(loaded, load_derived_maps(loaded).occupancy)
    assert stale is None and (world.parent / "twins.npz").is_file()
