"""A building from a point-cloud map (pimm_env/importers/cloud_map.py): made as SLAM makes one, imported, checked."""

from pathlib import Path

import numpy as np
import pytest
import yaml
from typer.testing import CliRunner

import evaluate
from pimm_env.bags.record import record_scenario
from pimm_env.clouds.pcd import write_pcd
from pimm_env.errors import MapFileError
from pimm_env.importers.world_import import import_world
from pimm_env.mapping.derived_maps import build_derived_maps, ensure_derived_maps
from pimm_env.mapping.occupancy import OccupancyGrid, resample_occupied, tolerant_iou
from pimm_env.world.files import load_world
from tests.conftest import shared_file
from tests.rooms import ROUTES

ROOM_CORNERS = np.array([[0.0, 0.0], [6.0, 0.0], [0.0, 4.0], [6.0, 4.0]])  # the fixture room's inside corners


def surface(rng, lo, hi, count, noise=0.02):
    """``count`` points spread over the box face from ``lo`` to ``hi`` (one coordinate equal), with noise."""
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    return lo + rng.uniform(size=(count, 3)) * (hi - lo) + rng.normal(0.0, noise, (count, 3))


def slam_like_room(rng: np.random.Generator, storeys: int = 1) -> np.ndarray:
    """The 6 m x 4 m room of ``room_file`` (3 m high, a post), as an accumulated map: noisy surfaces, the second
    half of the drive 3 cm off (a SLAM pose error), a desk hiding the walls' foot, and a person who walked
    through (a thin ghost)."""
    parts = []
    for level in range(storeys):
        z0 = 3.3 * level
        parts += [
            surface(rng, [0, 0, z0], [6, 4, z0], 60_000),  # floor
            surface(rng, [0, 0, z0 + 3], [6, 4, z0 + 3], 60_000),  # ceiling
            surface(rng, [0, 0, z0], [6, 0, z0 + 3], 40_000),
            surface(rng, [0, 4, z0], [6, 4, z0 + 3], 40_000),
            surface(rng, [0, 0, z0], [0, 4, z0 + 3], 30_000),
            surface(rng, [6, 0, z0], [6, 4, z0 + 3], 30_000),
        ]
    angle = rng.uniform(0, 2 * np.pi, 8000)
    parts.append(np.column_stack([4.5 + 0.2 * np.cos(angle), 2.0 + 0.2 * np.sin(angle), rng.uniform(0, 3, 8000)]))
    parts.append(surface(rng, [1.0, 3.2, 0.75], [2.6, 4.0, 0.75], 3000))  # a desk top against the north wall
    parts.append(surface(rng, [3.0, 1.0, 0.0], [3.3, 1.3, 1.8], 12))  # a passer-by, seen in a few scans
    points = np.vstack(parts)
    points[len(points) // 2 :] += [0.03, -0.02, 0.0]
    return points


def test_a_slam_like_map_of_a_room_imports_with_its_corners_and_what_it_set_aside(tmp_path):
    source = write_pcd(tmp_path / "room.pcd", slam_like_room(np.random.default_rng(0)))
    world_file = import_world(source, "room_map", tmp_path / "maps")
    world = load_world(world_file)
    maps = build_derived_maps(world)
    gaps = np.hypot(*(maps.corners.xy[:, None, :] - ROOM_CORNERS[None, :, :]).transpose(2, 0, 1))
    assert len(maps.corners) == 4 and gaps.min(axis=0).max() < 0.1  # each corner once, within 10 cm
    assert np.allclose(maps.corners.z, 3.0, atol=0.15)
    seen = np.load(world_file.parent / "seen_walls.npy")  # where the map saw walls: the room's four faces
    assert world.seen_walls is not None and len(seen) > 100 and np.abs(seen).max() < 6.5
    text = world_file.read_text()
    assert "sparse voxels" in text and "outliers" in text  # counted, not silently dropped
    free = maps.occupancy.free.sum() * maps.occupancy.grid.resolution**2
    assert 20.0 < free < 24.0  # the room's 24 m², less the post and the walls' faces


def test_a_map_of_two_storeys_or_of_no_floor_is_refused_before_anything_is_written(tmp_path):
    rng = np.random.default_rng(1)
    two = write_pcd(tmp_path / "two.pcd", slam_like_room(rng, storeys=2))
    with pytest.raises(MapFileError, match=r"two.pcd: the map holds more than one storey .*z = "):
        import_world(two, "two", tmp_path / "maps")
    hall = slam_like_room(rng)
    hall[:, 2] *= 5.5 / 3.0  # one storey, a hall 5.5 m high: its ceiling, with nothing over it, is no storey
    beside = slam_like_room(rng) + np.array([6.0, 0.0, 0.0])
    beside[:, 2] *= 2.5 / 3.0  # and beside it a room 2.5 m high: a hall's ceiling beside a ceiling is no storey
    import_world(write_pcd(tmp_path / "hall.pcd", np.vstack([hall, beside])), "hall", tmp_path / "halls")
    corridor = slam_like_room(rng) * np.array([0.5, 1.0, 2.5 / 3.0]) + np.array([6.0, 0.0, 0.0])
    # a corridor 3 m wide beside the hall: the hall's wall rises over the edge of the corridor's ceiling
    import_world(write_pcd(tmp_path / "hc.pcd", np.vstack([hall, corridor])), "hall_corridor", tmp_path / "halls")
    walls = write_pcd(tmp_path / "walls.pcd", surface(rng, [0, 0, 0], [0, 4, 3], 20_000))
    with pytest.raises(MapFileError, match="walls.pcd: no level surface"):
        import_world(walls, "walls", tmp_path / "maps")
    assert not (tmp_path / "maps").exists() or not any((tmp_path / "maps").iterdir())


def test_the_real_room_scan_imports_as_one_room_with_the_corners_its_planes_show(tmp_path):
    from pimm_agents.measurement.plane_reference import plane_reference
    from pimm_env.clouds.read import read_cloud

    scan = shared_file("real", "scans", "room_scan1.pcd")
    maps = build_derived_maps(load_world(import_world(scan, "room_scan", tmp_path / "maps")))
    reference = plane_reference(read_cloud(scan).points).corners  # the scan's own frame, levelled
    gaps = np.hypot(*(maps.corners.xy[:, None, :] - reference[None, :, :]).transpose(2, 0, 1))
    assert len(maps.corners) == len(reference) == 2 and gaps.min(axis=0).max() < 0.25


def test_a_bags_clouds_become_a_point_cloud_map_that_imports_as_the_room(room_file, tmp_path):
    (room_file.parent / "scenarios.yaml").write_text(ROUTES)
    ensure_derived_maps(load_world(room_file))
    bag = record_scenario("there", tmp_path / "bag", str(room_file), seed=0)
    out = tmp_path / "room.pcd"
    result = CliRunner().invoke(evaluate.app, ["map", "--from-bag", str(bag), "--cloud", str(out)])
    assert result.exit_code == 0, result.output
    assert f"then: python evaluate.py world import {out} --name NAME --trajectory {out.with_suffix('.tum')}" in (
        " ".join(result.output.split())
    )
    world = import_world(out, "from_bag", tmp_path / "maps", trajectory=out.with_suffix(".tum"))
    assert yaml.safe_load(world.read_text())["cloud_map"]["trajectory"]["poses"] > 10  # in the map's frame
    maps = build_derived_maps(load_world(world))
    own = ensure_derived_maps(load_world(room_file)).occupancy
    seen = resample_occupied(
        OccupancyGrid(maps.occupancy.grid, maps.occupancy.surfaces(), ~maps.occupancy.surfaces()), own.grid
    )
    assert tolerant_iou(seen, own.surfaces(), 2) > 0.8  # the walls the robot's clouds saw, where the room has them
    missing = CliRunner().invoke(evaluate.app, ["map", "--from-bag", str(bag)])
    assert missing.exit_code != 0 and "give --out MAP.yaml" in missing.output


def test_a_ply_without_faces_is_read_as_a_point_cloud_map(tmp_path):
    import trimesh

    points = slam_like_room(np.random.default_rng(2))
    source = Path(tmp_path / "room.ply")
    trimesh.PointCloud(points).export(source)
    world = load_world(import_world(source, "ply_room", tmp_path / "maps"))
    assert "cloud_map" in (tmp_path / "maps" / "ply_room" / "world.yaml").read_text()
    assert {e.semantic.name.lower() for e in world.elements} >= {"floor", "ceiling", "wall"}


def test_the_ghost_of_a_person_who_walked_by_is_set_aside_and_a_cabinet_kept():
    """A person walked along y = 2 while the room was mapped (the floor under the path was seen before and after);
    a cabinet stands in the south-east corner (the floor under it never seen)."""
    from pimm_env.importers.cloud_map import CLUTTER, classify

    rng = np.random.default_rng(1)
    room = slam_like_room(rng)
    cabinet = (room[:, 0] > 5.0) & (room[:, 1] < 1.1) & (room[:, 2] < 0.05)  # its footprint: no floor seen
    trail = rng.uniform([1.0, 1.8, 0.0], [4.0, 2.2, 1.7], (6000, 3))  # a person's sweep, 0 to 1.7 m
    sides = [
        surface(rng, [5.0, 0.2, 0.0], [5.0, 1.1, 1.9], 3000),  # its front
        surface(rng, [5.0, 1.1, 0.0], [5.45, 1.1, 1.9], 1500),  # its side
        surface(rng, [5.0, 0.2, 1.9], [5.45, 1.1, 1.9], 1500),  # its top
    ]
    cloud = classify(np.vstack([room[~cabinet], trail, *sides]))
    ghosts = next(n for key, n in cloud.set_aside.items() if key.startswith("ghosts"))
    clutter = (cloud.voxels[cloud.classes == CLUTTER] + 0.5) * cloud.voxel_m
    on_trail = (clutter[:, 0] > 1.2) & (clutter[:, 0] < 3.8) & (np.abs(clutter[:, 1] - 2.0) < 0.2)
    at_cabinet = (clutter[:, 0] > 4.9) & (clutter[:, 0] < 5.5) & (clutter[:, 1] < 1.2)
    assert ghosts > 100 and not on_trail.any()  # the trail is set aside, counted
    assert at_cabinet.sum() > 50  # the cabinet stays


def tall_cabinet(rng: np.random.Generator, front_y: float, back_y: float) -> list[np.ndarray]:
    """A 1.9 m cabinet from x 2 to 3 against a wall at ``back_y``: its front face and its top, as a map sees them."""
    return [
        surface(rng, [2.0, front_y, 0.0], [3.0, front_y, 1.9], 4000),
        surface(rng, [2.0, min(front_y, back_y), 1.9], [3.0, max(front_y, back_y), 1.9], 2000),
    ]


def under_cabinet(points: np.ndarray, front_y: float, back_y: float) -> np.ndarray:
    """Which of ``points`` are the floor under :func:`tall_cabinet` (never seen by a LiDAR), up to its wall."""
    x, y, z = points.T
    behind = y > front_y if back_y > front_y else y < front_y
    return (x > 2.0) & (x < 3.0) & behind & (z < 0.05)


def cabinet_front(cloud, front_y: float) -> np.ndarray:
    """The classes of the voxels of :func:`tall_cabinet`'s front, 1.2-2.7 m up."""
    centres = (cloud.voxels + 0.5) * cloud.voxel_m
    x, y, z = centres.T
    return cloud.classes[(z > 1.2) & (z < 2.7) & (np.abs(y - front_y) < 0.06) & (x > 2.1) & (x < 2.9)]


def test_a_far_wall_seen_only_as_the_lidars_rings_is_a_wall_and_a_cabinet_is_not():
    """The room's east wall seen from far (through a doorway): its points lie on the rings of a 16-beam LiDAR,
    0.3 m apart in height; a 1.9 m cabinet stands against the north wall, under the 3 m ceiling."""
    from pimm_env.importers.cloud_map import CLUTTER, WALL, classify

    rng = np.random.default_rng(2)
    room = slam_like_room(rng)
    east = room[:, 0] > 5.95
    rings = np.vstack([surface(rng, [6.0, 0.0, z], [6.0, 4.0, z], 400, noise=0.01) for z in np.arange(0.4, 2.9, 0.3)])
    cabinet = tall_cabinet(rng, front_y=3.5, back_y=4.0)
    under = under_cabinet(room, front_y=3.5, back_y=4.0)
    cloud = classify(np.vstack([room[~east & ~under], rings, *cabinet]))
    centres = (cloud.voxels + 0.5) * cloud.voxel_m
    high = (centres[:, 2] > 1.2) & (centres[:, 2] < 2.7)
    far = high & (centres[:, 0] > 5.9) & (centres[:, 1] > 0.3) & (centres[:, 1] < 3.7)
    assert np.mean(cloud.classes[far] == WALL) > 0.8
    front = cabinet_front(cloud, front_y=3.5)
    assert len(front) and np.all(front == CLUTTER)


def test_a_wall_rising_over_the_rooms_ceiling_holds_that_ceiling_up():
    """The room's north wall goes on over its 3 m ceiling to 5 m (as walls do over a suspended ceiling), seen up
    there only as a far LiDAR's rings from the next room: the wall's column tops out at 5 m with a gap over the
    ceiling. It is a wall up to the ceiling beside it; the cabinet against the south wall stays clutter."""
    from pimm_env.importers.cloud_map import CLUTTER, WALL, classify

    rng = np.random.default_rng(5)
    room = slam_like_room(rng)
    over = np.vstack([surface(rng, [0.0, 4.0, z], [6.0, 4.0, z], 600, noise=0.01) for z in np.arange(3.7, 5.0, 0.3)])
    cabinet = tall_cabinet(rng, front_y=0.5, back_y=0.0)
    under = under_cabinet(room, front_y=0.5, back_y=0.0)
    cloud = classify(np.vstack([room[~under], over, *cabinet]))
    centres = (cloud.voxels + 0.5) * cloud.voxel_m
    high = (centres[:, 2] > 1.2) & (centres[:, 2] < 2.7)
    north = high & (centres[:, 1] > 3.9) & (centres[:, 0] > 0.3) & (centres[:, 0] < 5.7)
    assert np.mean(cloud.classes[north] == WALL) > 0.9
    front = cabinet_front(cloud, front_y=0.5)
    assert len(front) and np.all(front == CLUTTER)
    along = [w for w in cloud.walls if abs(w[1] - w[3]) < 0.1 and abs(w[1] - 4.0) < 0.2]
    assert along and max(abs(w[2] - w[0]) for w in along) > 5.0


def test_a_rooms_floor_hidden_from_the_lidar_under_its_seen_ceiling_is_floor():
    """A room mapped through its doorway: the floor seen only near the door (x < 2), the ceiling over all of it.
    Its floor area reaches the far walls (where the corners are), not only the floor the LiDAR saw, and stops
    at the walls."""
    from shapely.geometry import Point, Polygon

    from pimm_env.importers.cloud_map import CloudMapConfig, classify, floor_areas

    rng = np.random.default_rng(3)
    parts = [
        surface(rng, [0, 0, 0], [2, 4, 0], 20_000),  # the floor seen
        surface(rng, [0, 0, 3], [6, 4, 3], 60_000),  # the ceiling, all of it
        surface(rng, [0, 0, 0], [2, 0, 3], 15_000),  # the walls: their foot seen near the door only
        surface(rng, [0, 4, 0], [2, 4, 3], 15_000),
        surface(rng, [0, 0, 0], [0, 4, 3], 30_000),
        surface(rng, [2, 0, 0.5], [6, 0, 3], 25_000),
        surface(rng, [2, 4, 0.5], [6, 4, 3], 25_000),
        surface(rng, [6, 0, 0.5], [6, 4, 3], 25_000),
        surface(rng, [5.0, 0.0, 0.0], [5.0, 1.0, 1.9], 3000),  # a cabinet's front in the far corner ...
        surface(rng, [5.0, 1.0, 0.0], [6.0, 1.0, 1.9], 3000),  # ... and its side
        surface(rng, [5.0, 0.0, 1.9], [6.0, 1.0, 1.9], 3000),  # ... and its top
    ]
    config = CloudMapConfig()
    areas = floor_areas(classify(np.vstack(parts), config), config)
    floor = [Polygon(ring) for ring in areas.values()]
    assert len(floor) == 1
    assert floor[0].covers(Point(5.7, 3.7))  # the far corner the LiDAR did not see the floor of
    assert not floor[0].covers(Point(6.2, 2.0)) and not floor[0].covers(Point(3.0, -0.2))
    assert 21.0 < floor[0].area < 26.5  # the room, and the rim of voxels its walls stand in


def test_the_free_space_reaches_a_far_wall_whose_foot_the_lidar_did_not_see(tmp_path):
    """A room seen from its west end: neither the floor nor the ceiling within 0.4 m of its east wall (hidden by
    the view), that wall seen from 0.6 m up. The occupancy's free space runs up to the wall, whose face is then
    one a sensor sees (the wall field scores scan points by their distance to such faces), and no further."""
    rng = np.random.default_rng(5)
    parts = [
        surface(rng, [0, 0, 0], [5.6, 4, 0], 50_000),  # the floor seen, short of the east wall
        surface(rng, [0, 0, 3], [5.6, 4, 3], 50_000),  # the ceiling seen, as short
        surface(rng, [0, 0, 0], [6, 0, 3], 30_000),
        surface(rng, [0, 4, 0], [6, 4, 3], 30_000),
        surface(rng, [0, 0, 0], [0, 4, 3], 25_000),
        surface(rng, [6, 0, 0.6], [6, 4, 3], 25_000),  # the east wall, its foot hidden
    ]
    world = load_world(import_world(write_pcd(tmp_path / "far.pcd", np.vstack(parts)), "far", tmp_path / "maps"))
    occupancy = build_derived_maps(world).occupancy
    x, y = occupancy.grid.cell_centers()
    face = occupancy.occupied & (np.abs(x - 6.0) < 0.15) & (y > 0.5) & (y < 3.5)
    assert face.sum() >= 60
    seen = occupancy.surfaces()
    rows = np.unique(np.flatnonzero(face.any(axis=1)))
    assert np.mean([seen[r][face[r]].any() for r in rows]) > 0.95  # the wall shows its face along its length
    assert not (occupancy.free & (x > 6.2)).any()  # nothing free behind it


@pytest.mark.parametrize("gap, filled", [(3, True), (6, True), (7, False)])
def test_the_floor_is_taken_up_to_a_wall_across_a_strip_up_to_twice_the_walls_foot(gap, filled):
    """Plan cells (a voxel column each): open floor, ``gap`` columns the LiDAR saw nothing of, then a wall; a
    cabinet in the strip stays out of the floor."""
    from pimm_env.importers.cloud_map import WALL_FOOT_VOXELS, _up_to_the_walls

    assert 2 * WALL_FOOT_VOXELS == 6
    floor, wall, clutter = (np.zeros((40, 30), dtype=bool) for _ in range(3))
    floor[:, :10] = True
    wall[:, 10 + gap] = True
    clutter[20, 11] = True
    added = _up_to_the_walls(floor, wall, clutter)
    rows = [r for r in range(8, 32) if r != 20]  # away from the plan's edges, which nothing closes
    strip = added[rows, 10 : 11 + gap]  # the unseen strip and the wall's column
    assert strip.all() if filled else not strip.any()
    assert not added[20, 11] and not added[:, 11 + gap :].any()


def test_the_ceiling_stops_at_the_walls_faces():
    """The ceiling's points scatter a voxel past the walls' faces; over a wall's body it is no ceiling (the
    corners behind a wall would stand under it)."""
    from pimm_env.importers.cloud_map import CloudMapConfig, classify, surface_meshes

    cloud_map = classify(slam_like_room(np.random.default_rng(4)), CloudMapConfig())
    low, high = surface_meshes(cloud_map)["ceiling"].bounds
    assert low[0] > -0.01 and low[1] > -0.01 and high[0] < 6.01 and high[1] < 4.01


def test_a_corner_a_cabinet_hides_is_closed_and_a_doorway_beside_a_corner_stays_open():
    """The SLAM-like room: a cabinet (0.45 m x 0.9 m) in its north-west corner hid both walls' faces near it from
    the drive, and its west wall has a doorway 0.9 m wide beside the south-west corner, the floor beyond and under
    it seen. The walls meet in the corner the cabinet hides; the doorway stays open."""
    from pimm_env.importers.cloud_map import CloudMapConfig, classify
    from pimm_env.importers.cloud_walls import in_walls

    rng = np.random.default_rng(6)
    points = np.vstack([slam_like_room(rng), surface(rng, [-1.5, 0, 0], [0, 0.9, 0], 6000)])  # floor past the door
    x, y, up = points[:, 0], points[:, 1], points[:, 2] > 0.05
    doorway = (np.abs(x) < 0.12) & (y < 0.9) & up  # the wall's points (the map's drift is 3 cm)
    shadow = ((x < 0.12) & (y > 3.1)) | ((y > 3.88) & (x < 0.45))  # the faces the cabinet hid ...
    under = (x < 0.45) & (y > 3.1) & ~up  # ... and the floor under it
    cabinet = [surface(rng, [0.45, 3.1, 0], [0.45, 4, 1.9], 3000), surface(rng, [0, 3.1, 0], [0.45, 3.1, 1.9], 1500)]
    walls = classify(np.vstack([points[~doorway & ~shadow & ~under], *cabinet]), CloudMapConfig()).walls
    assert not in_walls(np.column_stack([np.full(7, -0.05), np.linspace(0.1, 0.7, 7)]), walls).any()
    assert in_walls(np.array([[-0.05, 3.5], [-0.05, 3.95], [0.2, 4.05]]), walls).all()


def write_trajectory(path: Path, xy: np.ndarray, z: float = 0.5) -> Path:
    """A TUM trajectory file of positions ``xy`` (N, 2) at height ``z``, heading along x."""
    table = np.column_stack(
        [np.arange(len(xy)) * 0.1, xy, np.full(len(xy), z), np.zeros((len(xy), 3)), np.ones(len(xy))]
    )
    np.savetxt(path, table, header="timestamp x y z qx qy qz qw")
    return path


def test_clutter_where_the_robot_drove_is_set_aside_given_its_trajectory(tmp_path):
    """A person stood at (2, 1.5) while the room was mapped (the floor under them never seen, so the ghost rule
    keeps them); the robot drove through there later. With the trajectory they are set aside; a cabinet 0.6 m
    beside the path stays."""
    from pimm_env.importers.cloud_map import CLUTTER, classify
    from pimm_env.importers.cloud_path import read_path

    rng = np.random.default_rng(2)
    room = slam_like_room(rng)
    under = (np.abs(room[:, 0] - 2.0) < 0.25) & (np.abs(room[:, 1] - 1.5) < 0.25) & (room[:, 2] < 0.05)
    person = rng.uniform([1.8, 1.3, 0.0], [2.2, 1.7, 1.7], (4000, 3))
    cabinet = surface(rng, [3.5, 2.1, 0.0], [4.5, 2.1, 1.0], 2000)  # its front, 0.6 m north of the path
    points = np.vstack([room[~under], person, cabinet])
    path = read_path(
        write_trajectory(tmp_path / "path.tum", np.column_stack([np.linspace(0.5, 5.5, 60), np.full(60, 1.5)]))
    )

    def clutter_near(cloud, x, y, r):
        centres = (cloud.voxels[cloud.classes == CLUTTER] + 0.5) * cloud.voxel_m
        return int(np.count_nonzero(np.hypot(centres[:, 0] - x, centres[:, 1] - y) < r))

    without, with_path = classify(points), classify(points, path=path)
    cleared = next(n for key, n in with_path.set_aside.items() if key.startswith("clutter where the trajectory"))
    assert clutter_near(without, 2.0, 1.5, 0.2) > 20  # the ghost rule alone keeps the person
    assert clutter_near(with_path, 2.0, 1.5, 0.2) == 0 and cleared >= clutter_near(without, 2.0, 1.5, 0.2)
    assert clutter_near(with_path, 4.0, 2.15, 0.1) == clutter_near(without, 4.0, 2.15, 0.1) > 0  # the cabinet stays
    assert not any(key.startswith("clutter where") for key in without.set_aside)


FAR_AWAY = "".join(f"{k * 0.1} {100 + k} 50 0.5 0 0 0 1\n" for k in range(20))


@pytest.mark.parametrize(
    "name, text, source, said",
    [
        ("far.tum", FAR_AWAY, "room.pcd", r"far.tum: 20 of 20 poses of the trajectory lie outside the map .*frame"),
        ("poses.txt", "0 1 2\n", "room.pcd", r"poses.txt: not a TUM trajectory"),
        ("nan.tum", "0 1 1 0.5 0 0 0 1\n0.1 nan 1 0.5 0 0 0 1\n", "room.pcd", r"nan.tum: pose 2 is not finite"),
        ("far.tum", FAR_AWAY, "plan.yaml", r"--trajectory .*far.tum: a trajectory goes with a point-cloud map"),
    ],
)
def test_a_bad_trajectory_is_refused_naming_it_before_anything_is_written(name, text, source, said, tmp_path):
    write_pcd(tmp_path / "room.pcd", slam_like_room(np.random.default_rng(3)))
    (tmp_path / "plan.yaml").write_text("image: plan.pgm\n")
    (tmp_path / name).write_text(text)
    with pytest.raises(MapFileError, match=said):
        import_world(tmp_path / source, "room", tmp_path / "maps", trajectory=tmp_path / name)
    assert not (tmp_path / "maps" / "room").exists()


def test_world_import_takes_the_trajectory_and_says_what_it_set_aside(tmp_path):
    import yaml

    rng = np.random.default_rng(4)
    cloud = write_pcd(tmp_path / "room.pcd", slam_like_room(rng))
    path = write_trajectory(tmp_path / "path.tum", np.column_stack([np.linspace(0.5, 5.5, 30), np.full(30, 2.0)]))
    args = ["world", "import", str(cloud), "--name", "room", "--maps-dir", str(tmp_path / "maps"), "--no-prepare"]
    result = CliRunner().invoke(evaluate.app, [*args, "--trajectory", str(path)])
    assert result.exit_code == 0, result.output
    spec = yaml.safe_load((tmp_path / "maps" / "room" / "world.yaml").read_text())
    assert spec["cloud_map"]["trajectory"] == {"file": str(path), "poses": 30}
    assert any(key.startswith("clutter where the trajectory drove") for key in spec["cloud_map"]["set_aside"])


def _low_room_with_a_tall_cabinet(rng: np.random.Generator) -> np.ndarray:
    """A 6 m x 4 m room 2.5 m high whose south-west corner a 1.9 m cabinet (1.5 m x 0.5 m) hides up to its top,
    and in its north wall an opening 1.5 m wide under a header from 2.0 m, the floor beyond it seen."""
    parts = [
        surface(rng, [0, 0, 0], [6, 4, 0], 60_000),
        surface(rng, [0, 0, 2.5], [6, 4, 2.5], 60_000),
        surface(rng, [0, 0, 0], [6, 0, 2.5], 40_000),
        surface(rng, [0, 4, 0], [6, 4, 2.5], 40_000),
        surface(rng, [0, 0, 0], [0, 4, 2.5], 30_000),
        surface(rng, [6, 0, 0], [6, 4, 2.5], 30_000),
        surface(rng, [2, 4, 0], [3.5, 5, 0], 6000),  # the floor beyond the opening
    ]
    points = np.vstack(parts)
    hidden = (points[:, 0] < 1.5) & (points[:, 1] < 0.5) & (points[:, 2] < 1.9)  # behind and under the cabinet
    opening = (points[:, 0] > 2) & (points[:, 0] < 3.5) & (np.abs(points[:, 1] - 4) < 0.1) & (points[:, 2] < 2.0)
    cabinet = [surface(rng, [0, 0.5, 0], [1.5, 0.5, 1.9], 6000), surface(rng, [1.5, 0, 0], [1.5, 0.5, 1.9], 2000)]
    return np.vstack([points[~hidden & ~opening], *cabinet])


def test_a_walls_top_seen_over_a_tall_cabinet_closes_the_corner_it_hides_and_a_header_is_no_wall(tmp_path):
    """The cabinet's top stands 0.4 m under the ceiling band: the wall behind it is seen only over it (too short
    to be judged a wall), but on the wall's plane, over floor the map never saw: the wall runs on to the corner,
    standing from the cabinet's top. The header over the opening stands over floor the map saw: no wall."""
    source = write_pcd(tmp_path / "low.pcd", _low_room_with_a_tall_cabinet(np.random.default_rng(4)))
    world_file = import_world(source, "low_room", tmp_path / "maps")
    world = load_world(world_file)
    maps = build_derived_maps(world)
    gaps = np.hypot(*(maps.corners.xy[:, None, :] - ROOM_CORNERS[None, :, :]).transpose(2, 0, 1))
    assert len(maps.corners) == 4 and gaps.min(axis=0).max() < 0.1  # the hidden corner too
    walls = [e.shape for e in world.elements if e.semantic.name == "WALL"]
    raised = [w for w in walls if w.center[2] - w.half_extents[2] > 1.0]
    assert raised and all(abs(w.center[2] - w.half_extents[2] - 1.9) < 0.15 for w in raised)  # the cabinet's top
    assert all(w.center[0] < 1.6 for w in raised)  # none over the opening
