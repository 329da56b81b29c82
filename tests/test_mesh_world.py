import numpy as np
import pytest

from pimm_env.envs.base_env import LidarRobotEnv
from pimm_env.errors import WorldFileError
from pimm_env.mapping.derived_maps import ensure_derived_maps
from pimm_env.world.files import load_world
from pimm_env.world.mesh import read_obj
from pimm_env.world.semantics import SemanticClass

from .conftest import shared_file


def _box_obj(name: str, lo, hi, first: int) -> tuple[list[str], int]:
    """OBJ lines of an axis-aligned box (Y-up file coordinates: map (x, y, z) is file (x, z, -y))."""
    lines = [f"o {name}"]
    for z in (lo[2], hi[2]):
        for x, y in ((lo[0], lo[1]), (hi[0], lo[1]), (hi[0], hi[1]), (lo[0], hi[1])):
            lines.append(f"v {x} {z} {-y}")
    quads = [(1, 2, 3, 4), (5, 8, 7, 6), (1, 5, 6, 2), (2, 6, 7, 3), (3, 7, 8, 4), (4, 8, 5, 1)]
    lines += ["f " + " ".join(str(first + i - 1) for i in q) for q in quads]
    return lines, first + 8


@pytest.fixture
def mesh_world_file(tmp_path):
    parts = [
        ("Floor", (-1, -1, -0.1), (5, 5, 0.0)),
        ("Cealing_main", (-1, -1, 3.0), (5, 5, 3.1)),
        ("Wall1", (-0.2, -0.2, 0.0), (4.2, 0.0, 3.0)),
        ("Wall2", (-0.2, 4.0, 0.0), (4.2, 4.2, 3.0)),
        ("Wall3", (-0.2, 0.0, 0.0), (0.0, 4.0, 3.0)),
        ("Wall4", (4.0, 0.0, 0.0), (4.2, 4.0, 3.0)),
        ("Crate", (2.0, 2.0, 0.0), (2.5, 2.5, 0.5)),
    ]
    lines, first = ["# tiny test building"], 1
    for name, lo, hi in parts:
        box, first = _box_obj(name, lo, hi, first)
        lines += box
    (tmp_path / "room.obj").write_text("\n".join(lines) + "\n")
    (tmp_path / "world.yaml").write_text(
        "format: pimm-mesh-world/1\nname: tiny-mesh\nmesh: room.obj\nup_axis: y\n"
        "rules:\n  - {match: 'Cealing*', class: ceiling}\n  - {match: Floor, class: floor}\n"
        "  - {match: 'Wall*', class: wall}\n  - {match: '*', class: clutter}\n"
        "areas: {room: [[0, 0], [4, 0], [4, 4], [0, 4]]}\n"
    )
    return tmp_path / "world.yaml"


def test_obj_objects_are_read_in_the_map_frame(mesh_world_file):
    meshes = read_obj(mesh_world_file.parent / "room.obj", up_axis="y")
    assert set(meshes) == {"Floor", "Cealing_main", "Wall1", "Wall2", "Wall3", "Wall4", "Crate"}
    wall = meshes["Wall2"]
    assert wall.vertices[:, 1].min() == pytest.approx(4.0) and wall.vertices[:, 2].max() == pytest.approx(3.0)
    assert len(wall.triangles) == 12


def test_rules_assign_classes_and_the_env_runs_on_the_mesh(mesh_world_file):
    world = load_world(mesh_world_file)
    by_name = {e.name: e.semantic for e in world.elements}
    assert by_name["Cealing_main"] == SemanticClass.CEILING and by_name["Crate"] == SemanticClass.CLUTTER
    assert by_name["Floor"] == SemanticClass.FLOOR and by_name["Wall3"] == SemanticClass.WALL
    ensure_derived_maps(world)
    env = LidarRobotEnv(world=world)
    try:
        _, info = env.reset(seed=0, options={"pose": [1.0, 1.0, 0.0]})
        labels = info["labels"]
        seen = set(np.unique(labels[labels >= 0]).tolist())
        assert {int(SemanticClass.WALL), int(SemanticClass.FLOOR), int(SemanticClass.CEILING)} <= seen
        assert env.maps.occupancy.occupied.any()
        with pytest.raises(ValueError, match="inside an obstacle"):
            env.reset(options={"pose": [2.0, 2.25, 0.0]})  # on the crate's face (mesh solids are hollow)
    finally:
        env.close()


def test_mesh_world_errors_name_the_field(tmp_path, mesh_world_file):
    bad = tmp_path / "bad.yaml"
    bad.write_text("format: pimm-mesh-world/1\nmesh: room.obj\nrules:\n  - {match: 'Wall*', class: wall}\n")
    with pytest.raises(WorldFileError, match=r"bad.yaml: rules: no rule matches object 'Floor'"):
        load_world(bad)
    bad.write_text("format: pimm-mesh-world/1\nmesh: missing.obj\nrules: [{match: '*', class: wall}]\n")
    with pytest.raises(WorldFileError, match="mesh: file .*missing.obj does not exist"):
        load_world(bad)
    (tmp_path / "broken.obj").write_text("v 1 2\n")
    bad.write_text("format: pimm-mesh-world/1\nmesh: broken.obj\nrules: [{match: '*', class: wall}]\n")
    with pytest.raises(ValueError, match=r"broken.obj:1"):
        load_world(bad)


def test_iilab_mesh_world_is_available_with_the_reference_data():
    shared_file("iilab", "iilab.obj")
    world = load_world("iilab-mesh")
    assert len(world.elements) == 99
    classes = {e.name: e.semantic for e in world.elements}
    assert classes["Cealing_004"] == SemanticClass.CEILING and classes["Wall1"] == SemanticClass.WALL
    assert classes["RoundedPosts"] == SemanticClass.CLUTTER and classes["Floor"] == SemanticClass.FLOOR


def test_a_mesh_world_takes_solid_elements_beside_its_objects(mesh_world_file):
    text = mesh_world_file.read_text()
    mesh_world_file.write_text(
        text + "elements:\n  - {name: post, class: clutter, cylinder: {center: [1, 1], radius: 0.2, z: [0, 3]}}\n"
    )
    post = {e.name: e for e in load_world(mesh_world_file).elements}["post"]
    assert post.semantic == SemanticClass.CLUTTER and post.occupancy
    twice = "elements:\n  - {name: Wall1, class: wall, box: {min: [0, 0, 0], max: [1, 1, 1]}}\n"
    mesh_world_file.write_text(text + twice)
    with pytest.raises(WorldFileError, match=r"elements\[0\] \(Wall1\)\.name: duplicate element name"):
        load_world(mesh_world_file)
    mesh_world_file.write_text(text + "elements: {post: 1}\n")
    with pytest.raises(WorldFileError, match="elements: expected a list of world elements"):
        load_world(mesh_world_file)


def test_a_scanned_world_keeps_only_the_corners_whose_faces_were_seen(mesh_world_file):
    from pimm_env.mapping.corner_map import derive_corner_map

    all_four = derive_corner_map(load_world(mesh_world_file))
    assert len(all_four) == 4
    # the scan saw the room's south wall (y = 0) and, 5 cm off it, a stretch of the west wall near (0, 4)
    south = np.column_stack([np.arange(0.0, 4.01, 0.05), np.full(81, 0.01)])
    west = np.column_stack([np.full(7, 0.03), np.linspace(3.6, 3.9, 7)])
    np.save(mesh_world_file.parent / "seen.npy", np.vstack([south, west]))
    mesh_world_file.write_text(mesh_world_file.read_text() + "seen_walls: seen.npy\n")
    world = load_world(mesh_world_file)
    kept = derive_corner_map(world)
    near = [np.min(np.hypot(*(kept.xy - corner).T)) if len(kept) else 9.0 for corner in ((0, 0), (0, 4), (4, 0))]
    assert len(kept) == 3 and max(near) <= 0.1  # one cell of the raster; (4, 4), no face of it seen, is a guess
    assert len(ensure_derived_maps(world).corners) == 3
    # a wall seen 10 cm off a face (a guessed back, behind the face the scan saw) is not that face
    np.save(mesh_world_file.parent / "seen.npy", np.column_stack([np.arange(0.0, 4.01, 0.05), np.full(81, -0.1)]))
    assert len(derive_corner_map(load_world(mesh_world_file))) == 0


@pytest.mark.parametrize(
    ("saved", "message"),
    [
        (np.zeros((3, 3)), r"seen.npy: expected \(S, 2\) numbers, got float64 \(3, 3\)"),
        (np.array([[0.0, np.nan]]), "seen.npy: 1 values not finite"),
        (None, "seen_walls: cannot read .*seen.npy"),
    ],
)
def test_seen_walls_errors_name_the_field_and_the_file(mesh_world_file, saved, message):
    if saved is not None:
        np.save(mesh_world_file.parent / "seen.npy", saved)
    mesh_world_file.write_text(mesh_world_file.read_text() + "seen_walls: seen.npy\n")
    with pytest.raises(WorldFileError, match=message):
        load_world(mesh_world_file)
