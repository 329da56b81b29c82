import numpy as np
import pytest

from pimm_env.errors import WorldFileError
from pimm_env.world.files import load_world, world_from_spec
from pimm_env.world.model import point_in_polygon
from pimm_env.world.semantics import SemanticClass
from pimm_env.world.shapes import Box


def test_iilab_world_has_every_kind_of_structure():
    world = load_world("iilab")
    classes = {e.semantic for e in world.elements}
    assert classes == set(SemanticClass)
    assert world.ceiling_heights() == [3.01, 3.91, 7.91]
    assert set(world.areas) == {"A", "B", "C"}
    names = [e.name for e in world.elements]
    assert sum(n.startswith("c_post") for n in names) == 10
    assert any("glass" in n for n in names) and any("sliding_door" in n for n in names)
    assert any("beam" in n for n in names) and any("duct" in n for n in names)
    # Beams and ducts hang under the ceilings but are not part of the occupancy map.
    assert all(not e.occupancy for e in world.elements if "beam" in e.name or "duct" in e.name)


def test_point_in_polygon_agrees_with_shapely_on_a_concave_outline():
    from shapely.geometry import Point, Polygon

    rng = np.random.default_rng(0)
    angles = np.sort(rng.uniform(0, 2 * np.pi, 40))
    outline = np.column_stack([np.cos(angles), np.sin(angles)]) * rng.uniform(1.0, 4.0, (40, 1))  # a star
    shape = Polygon(outline)
    for x, y in rng.uniform(-4.5, 4.5, (2000, 2)):
        if shape.exterior.distance(Point(x, y)) > 1e-9:
            assert point_in_polygon(x, y, outline) == shape.contains(Point(x, y)), (x, y)


def test_iilab_areas_and_doorways():
    world = load_world("iilab")
    assert world.area_of(-10.0, 4.0) == "A"
    assert world.area_of(-10.0, 10.8) == "C"
    assert world.area_of(-20.0, 16.0) == "B"
    grid = world.grid(0.05)
    walls = world.footprint(grid, world.floor_z + 1.0, occupancy_only=True)
    rows, cols, _ = grid.cells_of(np.array([[-24.0, 8.77], [-24.0, 12.86], [-22.0, 8.83]]))
    assert not walls[rows[0], cols[0]] and not walls[rows[1], cols[1]], "doorways A-C and C-B must be open"
    assert walls[rows[2], cols[2]], "the sliding door beside the doorway is shut"


def test_room_world_from_file(room_file):
    world = load_world(room_file)
    assert world.name == "room"
    north = next(e for e in world.elements if e.name == "north")
    assert isinstance(north.shape, Box)
    assert north.shape.half_extents[0] == pytest.approx(3.1 + 0.1)  # segment plus half the thickness
    lower, upper = world.bounds()
    assert lower[0] <= -0.2 and upper[0] >= 6.2


@pytest.mark.parametrize(
    ("patch", "field", "value"),
    [
        ({"class": "wal"}, "elements[0] (w).class", "'wal'"),
        ({"box": {"min": [0, 0, 0], "max": [1, 0, 1]}}, "elements[0] (w).box.max", "min [0.0, 0.0, 0.0]"),
        ({"box": {"min": [0, 0], "max": [1, 1, 1]}}, "elements[0] (w).box.min", "[0, 0]"),
        ({"occupancy": "yes"}, "elements[0] (w).occupancy", "'yes'"),
        ({"colour": "red"}, "elements[0] (w).colour", "unknown key"),  # once silently ignored
        (
            {"cylinder": {"center": [0, 0], "radius": -1, "z": [0, 1]}, "box": None},
            "elements[0] (w).cylinder.radius",
            "-1",
        ),
    ],
)
def test_bad_element_names_file_field_and_value(tmp_path, patch, field, value):
    element = {"name": "w", "class": "wall", "box": {"min": [0, 0, 0], "max": [1, 1, 1]}}
    element.update(patch)
    element = {k: v for k, v in element.items() if v is not None}
    spec = {"format": "pimm-world/1", "name": "x", "areas": {"a": [[0, 0], [1, 0], [1, 1]]}, "elements": [element]}
    with pytest.raises(WorldFileError) as err:
        world_from_spec(spec, tmp_path / "bad.yaml")
    message = str(err.value)
    assert "bad.yaml" in message and field in message and value in message


def test_bad_world_files(tmp_path):
    path = tmp_path / "w.yaml"
    path.write_text("format: pimm-world/2\nname: x\n")
    with pytest.raises(WorldFileError, match=r"w.yaml: format: .*pimm-world/2"):
        load_world(path)
    path.write_text("format: pimm-world/1\nname: x\nareas: {}\nelements: []\n")
    with pytest.raises(WorldFileError, match="areas"):
        load_world(path)
    path.write_text("format: pimm-world/1\nname: x\nareas: {a: [[0, 0], [1, 0]]}\nelements: []\n")
    with pytest.raises(WorldFileError, match=r"areas\.a"):
        load_world(path)
    with pytest.raises(FileNotFoundError, match="known worlds: .*iilab"):
        load_world("no-such-world")


def test_duplicate_element_names_are_rejected(tmp_path):
    el = {"name": "w", "class": "wall", "box": {"min": [0, 0, 0], "max": [1, 1, 1]}}
    spec = {"format": "pimm-world/1", "name": "x", "areas": {"a": [[0, 0], [1, 0], [1, 1]]}, "elements": [el, el]}
    with pytest.raises(WorldFileError, match="duplicate element name 'w'"):
        world_from_spec(spec, tmp_path / "w.yaml")
