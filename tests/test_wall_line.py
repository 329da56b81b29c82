"""Objects standing in a wall's line (windows, closed doors) take the wall's class at import."""

import numpy as np
import pytest

from pimm_env.errors import WorldFileError
from pimm_env.importers.wall_line import footprint_rectangle, wall_line_objects
from pimm_env.world.model import Element
from pimm_env.world.semantics import SemanticClass
from pimm_env.world.shapes import Mesh


def box(name: str, lo, hi, semantic: SemanticClass = SemanticClass.CLUTTER) -> Element:
    import trimesh

    mesh = trimesh.creation.box(bounds=np.array([lo, hi], dtype=float))
    return Element(name, semantic, Mesh(np.asarray(mesh.vertices), np.asarray(mesh.faces)), True)


def wall(name: str, lo, hi) -> Element:
    return box(name, lo, hi, SemanticClass.WALL)


def room_with_openings() -> list[Element]:
    """A 10 x 6 m room of 0.2 m walls, 3 m high: the south wall has a 2 m opening at x 2-4 and a 4 m one at
    x 5-9, the east wall a doorway at y 2-3; the walls over the openings (lintels) are separate pieces."""
    return [
        wall("south_a", [0, -0.2, 0], [2, 0, 3]),
        wall("south_b", [4, -0.2, 0], [5, 0, 3]),
        wall("south_c", [9, -0.2, 0], [10, 0, 3]),
        wall("lintels", [2, -0.2, 2.2], [9, 0, 3]),
        wall("north", [0, 6, 0], [10, 6.2, 3]),
        wall("west", [-0.2, -0.2, 0], [0, 6.2, 3]),
        wall("east_a", [10, -0.2, 0], [10.2, 2, 3]),
        wall("east_b", [10, 3, 0], [10.2, 6.2, 3]),
    ]


def test_windows_and_a_closed_door_in_the_walls_line_are_found_and_nothing_else():
    elements = [
        *room_with_openings(),
        box("window", [2.0, -0.15, 0.8], [4.0, -0.05, 2.2]),  # fills the first opening (overlaps its jambs)
        box("pane_1", [4.98, -0.14, 0.8], [7.0, -0.06, 2.2]),  # two panes side by side fill the second
        box("pane_2", [7.0, -0.14, 0.8], [9.02, -0.06, 2.2]),
        box("door", [10.05, 2.0, 0.0], [10.15, 3.0, 2.1]),  # closed, in the east doorway
        box("picture", [1.0, 5.97, 1.2], [2.0, 6.0, 1.8]),  # on the north wall: the wall runs alongside it
        box("cabinet", [6.0, 5.4, 0.0], [8.0, 6.0, 2.0]),  # against the north wall: too deep
        box("shelf", [-0.0, 3.0, 1.0], [0.25, 5.0, 1.05]),  # a board on the west wall
        box("open_leaf", [9.1, 3.0, 0.0], [10.0, 3.05, 2.1]),  # an open door leaf: a wall at its hinge only
        # a ring of boards standing on its own, each closing the next one's end (corners met diagonally)
        box("board_a", [4.0, 3.0, 0.0], [6.0, 3.05, 1.0]),
        box("board_b", [6.0, 3.05, 0.0], [6.05, 5.0, 1.0]),
        box("board_c", [4.0, 5.0, 0.0], [6.0, 5.05, 1.0]),
        box("board_d", [3.95, 3.05, 0.0], [4.0, 5.0, 1.0]),
        box("handle", [10.16, 2.8, 1.0], [10.2, 2.9, 1.05]),  # on the door: too small
    ]
    assert wall_line_objects(elements) == ["door", "pane_1", "pane_2", "window"]


def test_windows_round_a_corner_close_each_others_ends():
    # a glass corner: the walls stop 2 m short of their corner, and a window runs on from each to meet there
    south, west = wall("south", [2, -0.2, 0], [6, 0, 3]), wall("west", [-0.2, 2, 0], [0, 6, 3])
    window_south = box("window_south", [-0.12, -0.15, 0.5], [2.02, -0.05, 2.2])
    window_west = box("window_west", [-0.15, -0.05, 0.5], [-0.05, 2.02, 2.2])
    assert wall_line_objects([south, west, window_south, window_west]) == ["window_south", "window_west"]
    # without the walls nothing anchors them: two panes meeting at a corner in the open are clutter
    assert wall_line_objects([window_south, window_west]) == []


def test_the_footprint_rectangle_is_the_smallest_enclosing_one():
    angle = np.radians(30.0)
    along, across = np.array([np.cos(angle), np.sin(angle)]), np.array([-np.sin(angle), np.cos(angle)])
    corners = np.array([s * 1.5 * along + c * 0.1 * across for s in (-1, 1) for c in (-1, 1)]) + np.array([2.0, 1.0])
    centre, unit, half_length, half_width = footprint_rectangle(corners)
    np.testing.assert_allclose(centre, [2.0, 1.0], atol=1e-9)
    assert abs(abs(unit @ along) - 1.0) < 1e-9
    assert half_length == pytest.approx(1.5) and half_width == pytest.approx(0.1)


def test_the_world_file_lists_them_and_names_a_bad_entry(tmp_path):
    import trimesh

    from pimm_env.importers.world_import import import_world
    from pimm_env.world.files import load_world

    scene = trimesh.Scene()
    for element in [*room_with_openings(), box("RoomWindow_01", [2.0, -0.15, 0.8], [4.0, -0.05, 2.2])]:
        name = element.name if element.semantic != SemanticClass.WALL else f"Wall_{element.name}"
        assert isinstance(element.shape, Mesh)
        scene.add_geometry(trimesh.Trimesh(element.shape.vertices, element.shape.triangles), node_name=name)
    import trimesh.creation

    scene.add_geometry(trimesh.creation.box(bounds=[[-0.5, -0.5, -0.1], [10.5, 6.5, 0.0]]), node_name="Floor")
    scene.export(tmp_path / "house.glb")
    path = import_world(tmp_path / "house.glb", "house", tmp_path / "maps", ceiling_height=3.0)
    import yaml

    spec = yaml.safe_load(path.read_text())
    assert spec["wall_line"] == ["RoomWindow_01"]
    classes = {e.name: e.semantic for e in load_world(path).elements}
    assert classes["RoomWindow_01"] == SemanticClass.WALL  # the rules alone would say clutter
    kept = import_world(tmp_path / "house.glb", "names", tmp_path / "maps", ceiling_height=3.0, wall_line=False)
    assert "wall_line" not in yaml.safe_load(kept.read_text())  # --no-wall-line: the names' classes
    assert {e.name: e.semantic for e in load_world(kept).elements}["RoomWindow_01"] == SemanticClass.CLUTTER
    spec["wall_line"] = ["RoomWindow_02"]
    path.write_text(yaml.safe_dump(spec))
    with pytest.raises(WorldFileError, match="wall_line.*RoomWindow_02"):
        load_world(path)
