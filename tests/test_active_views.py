"""The map-aware part of the ``greedy`` policy: predicted views, the place that tells twins apart, the guide."""

import numpy as np

from pimm_agents.active.explorer import Explorer
from pimm_agents.active.guide import Guide, distinct_hypotheses
from pimm_agents.active.policies import FORWARD, LEFT, RIGHT, Greedy
from pimm_agents.active.views import ViewPredictor, cast_ranges
from pimm_agents.localizer import Hypothesis, PoseEstimate
from pimm_env.mapping.free_graph import geodesic_from
from pimm_env.mapping.occupancy import OccupancyGrid
from pimm_env.world.grid import GridSpec


def corridor(length: float = 20.0, width: float = 2.0, resolution: float = 0.05) -> OccupancyGrid:
    """A closed corridor from x = 0 to ``length``, y = 0 to ``width``, walls one cell thick around it."""
    grid = GridSpec((-0.5, -0.5), resolution, (int((width + 1) / resolution), int((length + 1) / resolution)))
    gx, gy = grid.cell_centers()
    inside = (gx > 0) & (gx < length) & (gy > 0) & (gy < width)
    wall = ~inside & (gx > -0.1) & (gx < length + 0.1) & (gy > -0.1) & (gy < width + 0.1)
    return OccupancyGrid(grid, wall, inside)


def test_rays_stop_at_the_first_wall_and_at_the_view_range():
    occ = corridor()
    views = ViewPredictor(occ)
    ranges = views.views(np.array([[4.0, 1.0, 0.0]]), np.array([0.0, np.pi / 2, np.pi]))[0]
    assert abs(ranges[0] - views.config.view_range_m) < 0.06  # the east end is 16 m off: capped
    assert abs(ranges[1] - 1.0) < 0.1  # the side wall
    assert abs(ranges[2] - 4.0) < 0.1  # the west end
    blocked = np.ones((3, 3), dtype=bool)
    assert cast_ranges(np.zeros((1, 2)), np.zeros(1), np.zeros(1), blocked, -1.5, -1.5, 1.0, 5.0)[0, 0] == 0.0


def test_the_telling_place_is_toward_the_nearer_end_that_only_one_hypothesis_would_see():
    occ = corridor()
    views = ViewPredictor(occ)
    # twins 5 m apart along a featureless corridor: only its ends tell them apart; the estimate believes it is
    # at x = 4, so the west end (4 m behind) is the nearest place where the two would see different things
    estimate = np.array([4.0, 1.0, 0.0])
    hypotheses = np.array([estimate, [9.0, 1.0, 0.0]])
    found = views.best_waypoint(estimate, hypotheses, np.array([0.5, 0.5]), min_move=1.0)
    assert found is not None
    waypoint, place, score = found
    assert place[0] < -1.0 and waypoint[0] < 0  # behind the robot, toward the west end
    assert score > 0
    # one place only, or twins that see the same everywhere reachable: nothing to go and see
    assert views.best_waypoint(estimate, hypotheses[:1], np.array([1.0])) is None


def test_hypotheses_within_the_right_margin_of_one_listed_before_are_one():
    twin = Hypothesis(9.0, 1.0, 0.0, 0.3, np.eye(3))
    estimate = PoseEstimate(
        4.0,
        1.0,
        0.0,
        np.eye(3),
        status="ambiguous",
        hypotheses=(Hypothesis(4.2, 1.0, 0.02, 0.7, np.eye(3)), twin, Hypothesis(9.3, 1.1, 0.0, 0.0, np.eye(3))),
    )
    poses, weights = distinct_hypotheses(estimate)
    assert len(poses) == 2 and np.allclose(poses[0], [4.0, 1.0, 0.0]) and np.allclose(weights, [0.7, 0.3])


BEARINGS = -np.pi + (np.arange(60) + 0.5) * 2 * np.pi / 60


def seen(occ: OccupancyGrid, pose: np.ndarray) -> np.ndarray:
    return ViewPredictor(occ).views(pose[None, :], BEARINGS)[0]


def test_the_guide_points_toward_the_telling_place_only_while_ambiguous():
    occ = corridor()
    truth = np.array([9.0, 1.0, 0.0])
    twins = (Hypothesis(4.0, 1.0, 0.0, 0.6, np.eye(3)), Hypothesis(9.0, 1.0, 0.0, 0.4, np.eye(3)))
    ambiguous = PoseEstimate(4.0, 1.0, 0.0, np.eye(3), status="ambiguous", hypotheses=twins)
    guide = Guide(occ)
    shown = guide(ambiguous, seen(occ, truth), BEARINGS, np.zeros(3))
    assert shown[3] == 1.0 and shown[1] < 0 and 0 < shown[2] <= 1  # behind the robot, toward the west end
    localized = PoseEstimate(9.0, 1.0, 0.0, np.eye(3), status="localized", hypotheses=twins)
    assert not guide(localized, seen(occ, truth), BEARINGS, np.zeros(3)).any()
    # a listed rival whose view does not fit the scan is left out: in a room, from off its centre, half a turn
    # looks different; with only the estimate left there is nothing to tell apart
    room, here = corridor(length=6.0, width=4.0), np.array([1.5, 2.0, 0.0])
    turned = (Hypothesis(*here, 0.6, np.eye(3)), Hypothesis(1.5, 2.0, np.pi, 0.4, np.eye(3)))
    blind = PoseEstimate(*here, np.eye(3), status="ambiguous", hypotheses=turned)
    assert not Guide(room)(blind, seen(room, here), BEARINGS, np.zeros(3)).any()


def observation(
    occ: OccupancyGrid, pose: np.ndarray, guide: np.ndarray, max_range: float = 20.0
) -> dict[str, np.ndarray]:
    return {
        "scan": (seen(occ, pose) / max_range).astype(np.float32),
        "odom_delta": np.zeros(3, dtype=np.float32),
        "hypotheses": np.zeros((5, 6), dtype=np.float32),
        "status": np.array([0, 1, 0], dtype=np.float32),
        "guide": guide.astype(np.float32),
    }


def test_greedy_follows_the_guide_and_explores_without_one():
    occ = corridor()
    truth = np.array([9.0, 1.0, 0.0])
    behind = np.array([np.sin(3.0), np.cos(3.0), 0.5, 1.0])
    greedy, explorer = Greedy(20.0), Explorer(20.0)
    greedy.reset(0)
    explorer.reset(0)
    assert greedy(observation(occ, truth, behind)) in (LEFT, RIGHT)  # the guide says behind: it turns
    assert explorer(observation(occ, truth, behind)) == FORWARD  # where exploring drives on
    greedy.reset(0)
    assert greedy(observation(occ, truth, np.zeros(4))) == FORWARD  # no guide: it explores
    ahead_but_walled = np.array([0.0, 1.0, 0.5, 1.0])
    greedy.reset(0)
    assert greedy(observation(occ, np.array([19.6, 1.0, 0.0]), ahead_but_walled)) != FORWARD  # the wall, 0.4 m on


def test_the_nearest_telling_place_is_where_the_views_first_differ_enough():
    views = ViewPredictor(corridor())
    here = np.array([4.0, 1.0, 0.0])
    assert views.nearest_telling(here, np.zeros((0, 3)), 10.0, 0.1) == 0.0  # no twin: already told
    # a twin 5 m east: at the start only the ray straight back (the west end at 4 m against 9 m) differs; nearer
    # the west end the oblique rays reach it too, and from the twin's place 5 m on they still meet side walls
    far = views.nearest_telling(here, np.array([[9.0, 1.0, 0.0]]), 10.0, 0.1)
    assert far is not None and 0.5 <= far <= 4.0
    assert views.nearest_telling(here, np.array([[9.0, 1.0, 0.0]]), 0.2, 0.1) is None  # out of reach


def test_the_guide_plans_to_the_nearest_place_that_tells_all_twins_apart():
    occ = corridor(length=40.0)
    truth = np.array([13.0, 1.0, 0.0])
    twins = (Hypothesis(8.0, 1.0, 0.0, 0.6, np.eye(3)), Hypothesis(13.0, 1.0, 0.0, 0.4, np.eye(3)))
    ambiguous = PoseEstimate(8.0, 1.0, 0.0, np.eye(3), status="ambiguous", hypotheses=twins)
    guide = Guide(occ)
    shown = guide(ambiguous, seen(occ, truth), BEARINGS, np.zeros(3))
    # a far plan: behind the robot, to the west end, where the view tells the estimate from every twin the map
    # has of it (the corridor's other places, either way round) and from the listed one
    assert shown[3] == 1.0 and shown[1] < -0.9 and shown[2] == 1.0
    assert guide.far is not None and guide.far[-1][0] < 1.5
    # the robot turned half round; the estimate jumped to the twin 5 m on: the plan keeps its course relative to
    # the robot (straight ahead now), instead of being made again from the twin
    turned = np.array([0.0, 0.0, np.pi])
    jumped = PoseEstimate(13.0, 1.0, np.pi, np.eye(3), status="ambiguous", hypotheses=twins[::-1])
    shown = guide(jumped, seen(occ, np.array([13.0, 1.0, np.pi])), BEARINGS, turned)
    assert shown[3] == 1.0 and shown[1] > 0.9
    assert guide.far is not None and abs(guide.far[-1][0] - (guide.far[0][0] - 7.5)) < 0.6
    # localized: nothing shown, the plan dropped
    done = PoseEstimate(13.0, 1.0, np.pi, np.eye(3), status="localized", hypotheses=twins[::-1])
    assert not guide(done, seen(occ, truth), BEARINGS, np.zeros(3)).any() and guide.far is None


def test_the_guides_paths_keep_to_the_middle_of_a_corridor():
    occ = corridor(length=20.0, width=2.0)
    views = ViewPredictor(occ)
    start, end = occ.grid.cells_of(np.array([[1.0, 0.5], [19.0, 0.5]]))[:2]
    for cost, middle in ((views.cost_plain, False), (views.cost_centred, True)):
        field = geodesic_from(views.passable, int(start[0]), int(start[1]), 1e9, cost)
        path = views._path(field, int(end[0]), int(end[1]))
        along = path[(path[:, 0] > 4.0) & (path[:, 0] < 16.0)]
        # the shortest path runs straight along the wall; the guide's moves out to 0.75 m from either wall
        assert np.all(np.abs(along[:, 1] - 1.0) <= 0.3) == middle


def test_neither_policy_drives_on_into_what_the_body_would_sweep():
    # open all round but for a door jamb 0.45 m off at 40 deg to the left: out of the guard's cone ahead (30 deg)
    # but in the lane the body sweeps; the guard would stop a forward at once, so neither chooses one
    scan = np.full(60, 8.0)
    sectors = -np.pi + (np.arange(60) + 0.5) * 2 * np.pi / 60
    scan[np.argmin(np.abs(sectors - np.radians(40.0)))] = 0.45
    obs = {
        "scan": (scan / 20.0).astype(np.float32),
        "odom_delta": np.zeros(3, dtype=np.float32),
        "hypotheses": np.zeros((5, 6), dtype=np.float32),
        "status": np.array([0, 1, 0], dtype=np.float32),
        "guide": np.array([0.0, 1.0, 0.5, 1.0], dtype=np.float32),  # the guide's waypoint straight ahead
    }
    explorer, greedy = Explorer(20.0), Greedy(20.0)
    explorer.reset(0)
    greedy.reset(0)
    assert explorer(obs) != FORWARD
    assert greedy(obs) != FORWARD
    scan[np.argmin(np.abs(sectors - np.radians(40.0)))] = 8.0  # the jamb gone: both drive on
    obs["scan"] = (scan / 20.0).astype(np.float32)
    explorer.reset(0)
    greedy.reset(0)
    assert explorer(obs) == FORWARD and greedy(obs) == FORWARD


def two_rooms(door: tuple[float, float] = (2.0, 3.0), resolution: float = 0.05) -> OccupancyGrid:
    """Two 5 x 5 m rooms side by side, the wall between them at x = 5 with a doorway from y = door[0] to door[1]."""
    grid = GridSpec((-0.5, -0.5), resolution, (int(6 / resolution), int(11 / resolution)))
    gx, gy = grid.cell_centers()
    inside = (gx > 0) & (gx < 10) & (gy > 0) & (gy < 5)
    wall = ~inside | ((np.abs(gx - 5.0) < 0.1) & ~((gy > door[0]) & (gy < door[1])))
    return OccupancyGrid(grid, wall & (gx > -0.1) & (gx < 10.1) & (gy > -0.1) & (gy < 5.1), inside & ~wall)


def test_the_guide_heads_for_a_doorway_square_on_not_for_its_jamb():
    occ = two_rooms()
    views = ViewPredictor(occ)

    def path_from(pose: np.ndarray) -> np.ndarray:
        r, c = occ.grid.cells_of(pose[None, :2])[:2]
        field = geodesic_from(views.passable, int(r[0]), int(c[0]), 1e9, views.cost_centred)
        end = occ.grid.cells_of(np.array([[8.0, 2.5]]))[:2]
        return views._path(field, int(end[0][0]), int(end[1][0]))

    def clear_way(pose: np.ndarray, point: np.ndarray) -> bool:
        steps = np.linspace(0.25, np.hypot(*(point - pose[:2])), 50)
        way = pose[:2] + steps[:, None] * (point - pose[:2]) / np.hypot(*(point - pose[:2]))
        r, c = occ.grid.cells_of(way)[:2]
        return bool(np.all(views.clearance[r, c] >= views.config.lane_m))

    # 0.8 m beside the doorway's middle: the path's points past the doorway are out of clear sight (the straight
    # way to them grazes the jamb); the guide shows the farthest point in it, no further than the doorway
    beside = np.array([4.0, 1.7, 0.0])
    path = path_from(beside)
    point = views.steer(path, 0, beside)
    assert clear_way(beside, point) and point[0] <= 5.1
    assert not clear_way(beside, path[np.argmin(np.abs(path[:, 0] - 6.0))])
    # square in front of it: the way runs through, and the guide looks up to 3 m along the path
    before = np.array([4.0, 2.5, 0.0])
    point = views.steer(path_from(before), 0, before)
    assert clear_way(before, point) and point[0] > 6.0


def test_a_plan_made_again_keeps_going_the_way_the_robot_faces_unless_back_is_much_nearer():
    occ = corridor(length=40.0)
    views = ViewPredictor(occ)
    here = np.array([16.0, 1.0, 0.0])  # facing east; the west end is nearer
    twins = np.array([[11.0, 1.0, 0.0], [21.0, 1.0, 0.0]])
    west, _ = views.telling_path(here, twins, 60.0, 0.1, 1.0)
    assert west[-1][0] < here[0]
    east, _ = views.telling_path(here, twins, 60.0, 0.1, 1.0, back_m=10.0)
    assert east[-1][0] > here[0] and np.all(east[:, 0] >= here[0] - 0.1)  # it leaves forwards
    nearer_back = np.array([6.0, 1.0, 0.0])  # 6 m from the west end, 34 from the east: back it goes
    back, _ = views.telling_path(nearer_back, twins - [10.0, 0.0, 0.0], 60.0, 0.1, 1.0, back_m=10.0)
    assert back[-1][0] < nearer_back[0]


def guide_at(bearing_deg: float) -> np.ndarray:
    b = np.radians(bearing_deg)
    return np.array([np.sin(b), np.cos(b), 0.5, 1.0])


def test_greedy_steps_aside_from_a_blocked_way_and_then_drives_past():
    # a door jamb 0.42 m off, 21 deg to the right: the way ahead is blocked, and so it is after turning right; the
    # guide's waypoint straight ahead (a little right): it turns left, where the way is clear, and drives on one
    # step there before it follows the guide again
    scan = np.full(60, 8.0)
    sectors = -np.pi + (np.arange(60) + 0.5) * 2 * np.pi / 60
    scan[np.argmin(np.abs(sectors - np.radians(-21.0)))] = 0.42
    obs = {
        "scan": (scan / 20.0).astype(np.float32),
        "odom_delta": np.zeros(3, dtype=np.float32),
        "hypotheses": np.zeros((5, 6), dtype=np.float32),
        "status": np.array([0, 1, 0], dtype=np.float32),
        "guide": guide_at(-5.0).astype(np.float32),
    }
    greedy = Greedy(20.0)
    greedy.reset(0)
    assert greedy(obs) == LEFT
    obs["scan"] = np.full(60, 8.0 / 20.0, dtype=np.float32)  # turned: the way is clear
    obs["guide"] = guide_at(-50.0).astype(np.float32)  # the waypoint now to the right: it still steps past first
    assert greedy(obs) == FORWARD
    assert greedy(obs) == RIGHT  # then it turns back toward the waypoint


def test_greedy_turns_to_and_fro_only_once_and_then_follows_the_guide_again():
    occ = corridor()
    here = np.array([9.0, 1.0, 0.0])
    greedy = Greedy(20.0)
    greedy.reset(0)
    assert greedy(observation(occ, here, guide_at(-90.0))) == RIGHT
    # the belief jumped and the guide now says left: it would turn back the way it just turned, so it explores
    # for a few primitives; afterwards it follows the guide's turns again, whichever way exploring last turned
    # (a rule that counted exploring's own turns had the robot spin on the spot for a whole episode)
    greedy(observation(occ, here, guide_at(90.0)))
    for _ in range(Greedy.EXPLORE_STEPS - 1):
        greedy(observation(occ, here, guide_at(90.0)))
    assert greedy(observation(occ, here, guide_at(90.0))) == LEFT
    assert greedy(observation(occ, here, guide_at(90.0))) == LEFT


def test_the_policies_forward_test_on_sectors_stops_wherever_the_guard_does():
    from pimm_agents.active.env import scan_sectors
    from pimm_agents.active.explorer import sector_bearings, sectors_blocked
    from pimm_agents.active.primitives import blocked_ahead

    bearings = np.radians(np.arange(360) - 180.0)
    full = np.full(360, 8.0)
    full[180 + 36] = 0.5  # a pillar's corner 0.5 m off at 36 deg: 0.294 m beside the heading, in the swept lane
    assert blocked_ahead(full, bearings)
    sectors = scan_sectors(full, 60, 10.0).astype(float) * 10.0
    # taken at its sector's centre (39 deg) the return is 0.315 m beside the heading, out of the lane; a forward
    # chosen on that was stopped by the guard at once
    assert not blocked_ahead(sectors, sector_bearings(60))
    assert sectors_blocked(sectors)
    full[180 + 36] = 8.0
    assert not sectors_blocked(scan_sectors(full, 60, 10.0).astype(float) * 10.0)
