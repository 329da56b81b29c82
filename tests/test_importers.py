"""World import: ROS maps (straight walls at any angle, negate, origin yaw, doorways) and meshes."""

import itertools
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial import cKDTree

from pimm_env.errors import MapFileError
from pimm_env.importers.world_import import import_world
from pimm_env.mapping.corner_map import derive_corner_map
from pimm_env.mapping.derived_maps import ensure_derived_maps
from pimm_env.mapping.map_server import read_ros_map
from pimm_env.world.files import load_world
from pimm_env.world.semantics import SemanticClass

RES = 0.05
#: Two rooms (8 x 5 m and 4 x 5 m) side by side, 0.15 m walls, a 0.9 m doorway between them; in room
#: coordinates (u, v), with their eight corners.
ROOM_CORNERS = [(-6, -2.5), (-6, 2.5), (2, -2.5), (2, 2.5), (2.15, -2.5), (2.15, 2.5), (6.15, -2.5), (6.15, 2.5)]


def write_map(folder: Path, angle_deg: float, origin=(0.0, 0.0, 0.0), negate=False) -> tuple[Path, np.ndarray]:
    """The two rooms drawn at ``angle_deg`` to the raster as a map_server map; returns it and the true corners."""
    rows, cols = 340, 400
    yy, xx = np.mgrid[0:rows, 0:cols]
    cx, cy = (xx + 0.5) * RES, (rows - yy - 0.5) * RES  # image row 0 is the top
    c, s = np.cos(np.radians(angle_deg)), np.sin(np.radians(angle_deg))
    u, v = c * (cx - 10) + s * (cy - 8.5), -s * (cx - 10) + c * (cy - 8.5)
    room1, room2 = (np.abs(u + 2) < 4) & (np.abs(v) < 2.5), (np.abs(u - 4.15) < 2) & (np.abs(v) < 2.5)
    outer = ((np.abs(u + 2) < 4.15) | (np.abs(u - 4.15) < 2.15)) & (np.abs(v) < 2.65)
    door = (np.abs(u - 2.075) < 0.1) & (np.abs(v) < 0.45)
    image = np.full((rows, cols), 205, np.uint8)  # unknown outside
    image[outer] = 0
    image[room1 | room2 | door] = 254
    if negate:
        image = 255 - image
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "plan.pgm").write_bytes(f"P5\n{cols} {rows}\n255\n".encode() + image.tobytes())
    (folder / "plan.yaml").write_text(
        f"image: plan.pgm\nresolution: {RES}\norigin: [{origin[0]}, {origin[1]}, {origin[2]}]\n"
        f"negate: {int(negate)}\noccupied_thresh: 0.65\nfree_thresh: 0.196\n"
    )
    ox, oy, yaw = origin
    corners = []
    for cu, cv in ROOM_CORNERS:  # room frame -> image frame -> map frame (origin with its yaw)
        x, y = 10 + c * cu - s * cv, 8.5 + s * cu + c * cv
        corners.append((ox + np.cos(yaw) * x - np.sin(yaw) * y, oy + np.sin(yaw) * x + np.cos(yaw) * y))
    return folder / "plan.yaml", np.array(corners)


def corner_errors(world_file: Path, truth: np.ndarray) -> tuple[int, np.ndarray]:
    corners = derive_corner_map(load_world(world_file))
    distance, _ = cKDTree(truth).query(corners.xy)
    return len(corners), distance


@pytest.mark.parametrize(("angle", "origin", "negate"), [(0.0, (1.0, 2.0, 0.5), True), (30.0, (-2.0, 1.0, 0.0), False)])
def test_a_map_becomes_straight_walls_with_exactly_the_rooms_corners(tmp_path, angle, origin, negate):
    source, truth = write_map(tmp_path / "src", angle, origin, negate)
    world_file = import_world(source, "plan", tmp_path / "maps")
    count, distance = corner_errors(world_file, truth)
    assert count == 8 and distance.max() < 0.02, f"{count} corners, {distance.round(3)} m from the true ones"
    world = load_world(world_file)
    walls = [e for e in world.elements if e.semantic == SemanticClass.WALL]
    assert len(walls) == 1 and len(walls[0].shape.holes) == 1, "one piece of walls around one free region"
    assert set(world.areas) == {"space_1"}, "the two rooms and the doorway are one free region"
    maps = ensure_derived_maps(world)
    free_m2 = maps.occupancy.free.sum() * maps.occupancy.grid.resolution**2
    assert free_m2 == pytest.approx(8 * 5 + 4 * 5 + 0.15 * 0.9, rel=0.03)


def test_origin_yaw_and_negate_are_honoured(tmp_path):
    plain, _ = write_map(tmp_path / "a", 0.0)
    turned, _ = write_map(tmp_path / "b", 0.0, origin=(3.0, -1.0, np.pi / 2), negate=True)
    a, b = read_ros_map(plain), read_ros_map(turned)
    assert (a.free == b.free).all() and (a.occupied == b.occupied).all()
    # yaw pi/2: the image's (2, 1) m lies at origin + (-1, 2)
    assert np.allclose(b.to_map(np.array([[2.0, 1.0]])), [[3.0 - 1.0, -1.0 + 2.0]])


def test_a_hollow_wall_is_filled(tmp_path):
    source, _ = write_map(tmp_path / "src", 0.0)
    image_path = source.parent / "plan.pgm"
    header, pixels = image_path.read_bytes()[:15], np.frombuffer(image_path.read_bytes()[15:], np.uint8)
    image = pixels.reshape(340, 400).copy()
    # a 3 m x 0.3 m partition in the big room drawn as an outline, free inside (y 7.55-7.85 m, x 5-8 m)
    image[183:189, 100:160] = 0
    image[184:188, 101:159] = 254
    image_path.write_bytes(header + image.tobytes())
    world = load_world(import_world(source, "plan", tmp_path / "maps"))
    assert len(world.areas) == 1, "the wall's inside is no free space of its own"
    walls = [e for e in world.elements if e.semantic == SemanticClass.WALL]
    assert len(walls) == 2, "the partition is a wall of its own, not clutter"
    occupancy = ensure_derived_maps(world).occupancy
    rows, cols, _ = occupancy.grid.cells_of(np.array([[6.5, 7.7]]))
    assert occupancy.occupied[rows[0], cols[0]], "the middle of the hollow wall is solid"


def test_furniture_is_seeded_and_keeps_passages(tmp_path):
    source, _ = write_map(tmp_path / "src", 0.0)
    first = load_world(import_world(source, "a", tmp_path / "maps", furnish_count=3, seed=4))
    again = load_world(import_world(source, "b", tmp_path / "maps", furnish_count=3, seed=4))
    pieces = [e for e in first.elements if e.semantic == SemanticClass.CLUTTER]
    assert len(pieces) == 3 and [e.shape for e in pieces] == [
        e.shape for e in again.elements if e.semantic == SemanticClass.CLUTTER
    ]


def test_bad_maps_are_named(tmp_path):
    source, _ = write_map(tmp_path / "src", 0.0)
    (source.parent / "plan.pgm").unlink()
    with pytest.raises(MapFileError, match=r"plan.yaml: image: file .*plan.pgm does not exist"):
        import_world(source, "x", tmp_path / "maps")
    source, _ = write_map(tmp_path / "src", 0.0)
    source.write_text(source.read_text().replace("resolution: 0.05", "resolution: -0.05"))
    with pytest.raises(MapFileError, match="resolution: expected metres per pixel"):
        import_world(source, "x", tmp_path / "maps")
    source, _ = write_map(tmp_path / "src", 0.0)
    (source.parent / "plan.pgm").write_bytes(b"P5\n20 10\n255\n" + bytes([0] * 200))
    with pytest.raises(MapFileError, match="plan.yaml.*no free space"):
        import_world(source, "x", tmp_path / "maps")


@pytest.mark.parametrize("name", ["../x", "", ".", "a/b", "-x", "x" * 101])
def test_a_name_that_is_not_one_folder_under_maps_is_refused_before_anything_is_written(tmp_path, name):
    source, _ = write_map(tmp_path / "src", 0.0)
    with pytest.raises(MapFileError, match="a world's name is one folder under maps/"):
        import_world(source, name, tmp_path / "maps")
    assert not (tmp_path / "maps").exists() and not (tmp_path / "x").exists()


@pytest.mark.parametrize("height", [float("nan"), float("inf"), -1.0, 0.0])
def test_a_ceiling_height_that_is_not_a_positive_number_is_refused(tmp_path, height):
    source, _ = write_map(tmp_path / "src", 0.0)
    with pytest.raises(MapFileError, match="--ceiling-height: expected a positive height"):
        import_world(source, "x", tmp_path / "maps", ceiling_height=height)
    assert not (tmp_path / "maps" / "x").exists()


def test_a_mesh_without_faces_is_named_as_the_users_file(tmp_path):
    source = tmp_path / "points.obj"
    source.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\n")
    with pytest.raises(MapFileError, match=r"points.obj: the mesh has no faces"):
        import_world(source, "x", tmp_path / "maps")
    assert not (tmp_path / "maps" / "x").exists()
    source.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf -3 -2 -1\n")  # one triangle, nothing to stand on
    with pytest.raises(MapFileError, match=r"points.obj: imported as a world, areas: no areas given and no floor"):
        import_world(source, "x", tmp_path / "maps")
    assert not (tmp_path / "maps" / "x").exists()


def _box_mesh(lo, hi):
    import trimesh

    return trimesh.creation.box(bounds=np.array([lo, hi], dtype=float))


def test_a_mesh_becomes_a_world_the_env_runs_in(tmp_path):
    import trimesh

    from pimm_env.envs.iilab_env import IILabEnv

    scene = trimesh.Scene()
    scene.add_geometry(_box_mesh([-0.5, -0.5, -0.1], [6.5, 4.5, 0.0]), node_name="Floor")
    scene.add_geometry(_box_mesh([-0.5, -0.5, 3.0], [6.5, 4.5, 3.1]), node_name="Ceiling")
    for k, (lo, hi) in enumerate(
        [
            ([-0.2, -0.2, 0], [6.2, 0, 3]),
            ([-0.2, 4, 0], [6.2, 4.2, 3]),
            ([-0.2, 0, 0], [0, 4, 3]),
            ([6, 0, 0], [6.2, 4, 3]),
        ]
    ):
        scene.add_geometry(_box_mesh(lo, hi), node_name=f"Wall_{k}")
    scene.add_geometry(_box_mesh([3.0, 1.5, 0.0], [3.6, 2.1, 0.8]), node_name="crate")
    source = tmp_path / "room.glb"
    scene.export(source)
    world = load_world(import_world(source, "room", tmp_path / "maps"))
    classes = {e.name: e.semantic for e in world.elements}
    assert classes["Floor"] == SemanticClass.FLOOR and classes["Wall_2"] == SemanticClass.WALL
    assert classes["crate"] == SemanticClass.CLUTTER and classes["Ceiling"] == SemanticClass.CEILING
    assert world.floor_z == pytest.approx(0.0)
    ensure_derived_maps(world)
    env = IILabEnv(world=world)
    try:
        _, info = env.reset(seed=0, options={"pose": [1.5, 2.0, 0.0]})
        seen = set(np.unique(info["labels"][info["labels"] >= 0]).tolist())
        assert seen == {int(c) for c in SemanticClass}
    finally:
        env.close()
    no_floor = trimesh.Scene()
    no_floor.add_geometry(_box_mesh([0, 0, 0], [1, 1, 1]), node_name="Wall")
    no_floor.export(tmp_path / "bare.ply")
    with pytest.raises(MapFileError, match=r"bare.ply: imported as a world, areas: .*no floor object"):
        import_world(tmp_path / "bare.ply", "bare", tmp_path / "maps")


def test_generated_routes_keep_their_clearance_and_repeat_per_seed(tmp_path):
    from pimm_env.driving.routes import RouteConfig, plan_routes

    source, _ = write_map(tmp_path / "src", 30.0)
    occupancy = ensure_derived_maps(load_world(import_world(source, "plan", tmp_path / "maps"))).occupancy
    config = RouteConfig(count=2)
    routes = plan_routes(occupancy, config, seed=5)
    assert all(np.array_equal(a, b) for a, b in zip(routes, plan_routes(occupancy, config, seed=5), strict=True))
    clearance = occupancy.distance_to_occupied()
    free = occupancy.free
    for waypoints in routes:
        length = float(np.hypot(*np.diff(waypoints, axis=0).T).sum())
        assert config.min_length_m <= length <= config.max_length_m
        for a, b in itertools.pairwise(waypoints):
            samples = a + np.linspace(0, 1, 50)[:, None] * (b - a)
            rows, cols, valid = occupancy.grid.cells_of(samples)
            assert valid.all() and free[rows, cols].all()
            assert clearance[rows, cols].min() >= config.clearance_m - config.step_m


def test_world_import_command_prepares_a_world_to_run_in(tmp_path):
    from typer.testing import CliRunner

    import evaluate

    source, _ = write_map(tmp_path / "src", 30.0)
    args = ["world", "import", str(source), "--name", "plan", "--maps-dir", str(tmp_path / "maps"), "--furnish", "2"]
    result = CliRunner().invoke(evaluate.app, [*args, "--routes", "2"])
    assert result.exit_code == 0, result.output
    folder = tmp_path / "maps" / "plan"
    assert {"world.yaml", "occupancy.pgm", "corners.yaml", "fingerprints.npz", "scenarios.yaml", "twins.npz"} <= {
        p.name for p in folder.iterdir()
    }
    from pimm_env.driving.scenarios import load_scenarios

    assert list(load_scenarios(load_world(folder / "world.yaml"))) == ["route_1", "route_2", "route_1_kidnap"]
    bad = CliRunner().invoke(evaluate.app, ["world", "import", str(tmp_path / "nope.yaml"), "--name", "x"])
    assert bad.exit_code != 0 and "nope.yaml: no such file" in bad.output


def test_a_maps_unknown_exterior_stays_unknown_and_amcl_converges_in_it(tmp_path):
    from pimm_agents.experiments.runner import run_trial
    from pimm_agents.scoring.trial import TrialSpec

    source, _ = write_map(tmp_path / "src", 0.0)  # unknown (205) all around the two rooms
    world_file = import_world(source, "plan", tmp_path / "maps")
    occupancy = ensure_derived_maps(load_world(world_file)).occupancy
    # the outer wall's face is at x = 3.85 (v = 0): its cells are wall, what lies 0.35 m and more beyond is unknown
    rows, cols, valid = occupancy.grid.cells_of(np.array([[3.9, 8.5], [3.5, 8.5], [3.2, 8.5], [4.5, 8.5]]))
    assert valid.all()
    assert occupancy.occupied[rows, cols].tolist() == [True, False, False, False]
    assert occupancy.free[rows, cols].tolist() == [False, False, False, True]
    # a tour of both rooms from a global start: AMCL found the pose in each of seeds 0-2 (8.5-14.1 s, 0.15 m)
    (world_file.parent / "scenarios.yaml").write_text(
        "format: pimm-scenarios/1\nworld: plan\nscenarios:\n  tour:\n    start: [5.0, 7.5, 0.0]\n"
        "    waypoints: [[5.0, 7.5], [11.0, 7.5], [11.0, 9.5], [5.0, 9.5], [5.0, 7.5], [11.0, 7.5], [12.1, 8.5],"
        " [14.5, 8.5], [14.5, 10.0], [13.0, 7.0]]\n    speed: 0.5\n"
    )
    result = run_trial(TrialSpec("tour", "amcl", 0, 0, world=str(world_file)))
    assert result.metrics.converged and result.metrics.position_error_m < 0.3
