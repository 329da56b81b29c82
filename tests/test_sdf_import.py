"""Gazebo SDF worlds and COLLADA meshes in: includes, poses, scales, units, primitives, name rules, ceilings."""

from pathlib import Path

import numpy as np
import pytest

from pimm_env.errors import MapFileError
from pimm_env.importers.sdf_world import read_mesh_file, read_sdf_world
from pimm_env.importers.world_import import import_world
from pimm_env.mapping.corner_map import derive_corner_map
from pimm_env.world.files import load_world
from pimm_env.world.mesh import classify
from pimm_env.world.semantics import SemanticClass

ROOM = (6.0, 4.0)  # inside size of the test room (m); walls 0.2 m thick, 3 m tall


def _cube_dae(path: Path, side: float, unit: float, up: str = "Z_UP") -> None:
    """A COLLADA cube of ``side`` file units with ``<unit meter=unit>``, its base on z = 0 (in its up axis)."""
    import trimesh

    cube = trimesh.creation.box(extents=[side, side, side])
    cube.apply_translation([0, 0, side / 2] if up == "Z_UP" else [0, side / 2, 0])
    positions = " ".join(f"{v:.6f}" for v in cube.vertices.ravel())
    indices = " ".join(str(i) for i in cube.faces.ravel())
    path.write_text(f"""<?xml version="1.0" encoding="utf-8"?>
<COLLADA xmlns="http://www.collada.org/2005/11/COLLADASchema" version="1.4.1">
  <asset><unit meter="{unit}" name="unit"/><up_axis>{up}</up_axis></asset>
  <library_geometries><geometry id="cube" name="cube"><mesh>
    <source id="cube-pos"><float_array id="cube-arr" count="{cube.vertices.size}">{positions}</float_array>
      <technique_common><accessor source="#cube-arr" count="{len(cube.vertices)}" stride="3">
        <param name="X" type="float"/><param name="Y" type="float"/><param name="Z" type="float"/>
      </accessor></technique_common></source>
    <vertices id="cube-vtx"><input semantic="POSITION" source="#cube-pos"/></vertices>
    <triangles count="{len(cube.faces)}"><input semantic="VERTEX" source="#cube-vtx" offset="0"/>
      <p>{indices}</p></triangles>
  </mesh></geometry></library_geometries>
  <library_visual_scenes><visual_scene id="scene"><node id="n" name="n">
    <instance_geometry url="#cube"/></node></visual_scene></library_visual_scenes>
  <scene><instance_visual_scene url="#scene"/></scene>
</COLLADA>
""")


def _box_link(name: str, center, size) -> str:
    return f"""<model name="{name}"><static>true</static><pose>{center[0]} {center[1]} {center[2]} 0 0 0</pose>
  <link name="link"><collision name="collision"><geometry><box><size>{size[0]} {size[1]} {size[2]}</size></box>
  </geometry></collision></link></model>"""


def _world(
    tmp_path: Path, ceiling: bool = True, crate_uri: str = "model://crate", scale: str = "2 2 2", ground: bool = False
) -> Path:
    """A 6 x 4 m room: four box walls, a box floor, a plane ceiling at 3 m facing down, a column and an
    included crate (a 25 cm COLLADA cube in centimetres, scaled by 2 and turned 90 degrees)."""
    models = tmp_path / "models"
    (models / "crate" / "meshes").mkdir(parents=True, exist_ok=True)
    _cube_dae(models / "crate" / "meshes" / "crate.dae", side=25.0, unit=0.01)
    (models / "crate" / "model.config").write_text(
        "<model><name>crate</name><sdf version='1.6'>model.sdf</sdf></model>"
    )
    (models / "crate" / "model.sdf").write_text(f"""<sdf version="1.6"><model name="crate">
  <link name="body"><pose>0 0 0 0 0 0</pose><collision name="collision"><geometry><mesh>
    <uri>model://crate/meshes/crate.dae</uri><scale>{scale}</scale></mesh></geometry></collision>
  <visual name="visual"><geometry><sphere><radius>5</radius></sphere></geometry></visual></link></model></sdf>""")
    w, h = ROOM
    parts = [
        _box_link("south_wall", (w / 2, -0.1, 1.5), (w + 0.4, 0.2, 3.0)),
        _box_link("north_wall", (w / 2, h + 0.1, 1.5), (w + 0.4, 0.2, 3.0)),
        _box_link("west_wall", (-0.1, h / 2, 1.5), (0.2, h, 3.0)),
        _box_link("east_wall", (w + 0.1, h / 2, 1.5), (0.2, h, 3.0)),
        _box_link("floor", (w / 2, h / 2, -0.05), (w + 0.4, h + 0.4, 0.1)),
        """<model name="column"><static>1</static><link name="link"><pose>1 1 1.5 0 0 0</pose>
          <collision name="c"><geometry><cylinder><radius>0.15</radius><length>3</length></cylinder></geometry>
          </collision></link></model>""",
        f"""<include><uri>{crate_uri}</uri><name>crate_1</name><pose>4 2 0 0 0 1.5708</pose></include>""",
    ]
    if ceiling:
        parts.append(f"""<model name="ceiling"><static>1</static><pose>{w / 2} {h / 2} 3 0 0 0</pose><link name="l">
          <collision name="c"><geometry><plane><normal>0 0 -1</normal><size>{w + 0.4} {h + 0.4}</size></plane>
          </geometry></collision></link></model>""")
    path = tmp_path / "room.world"
    path.write_text(
        f"<sdf version='1.6'><world name='default'><include><uri>model://sun</uri></include>"
        f"{'<include><uri>model://ground_plane</uri></include>' if ground else ''}"
        f"{''.join(parts)}</world></sdf>"
    )
    return path


def test_an_sdf_world_imports_to_the_right_classes_sizes_and_corners(tmp_path):
    with pytest.warns(UserWarning, match="left out model://ground_plane"):
        world = load_world(import_world(_world(tmp_path, ground=True), "room", tmp_path / "maps"))
    by_name = {e.name.split("::")[0]: e for e in world.elements}
    assert by_name["north_wall"].semantic == SemanticClass.WALL
    assert by_name["floor"].semantic == SemanticClass.FLOOR
    assert by_name["ceiling"].semantic == SemanticClass.CEILING
    assert by_name["column"].semantic == SemanticClass.CLUTTER and by_name["crate_1"].semantic == SemanticClass.CLUTTER
    crate = by_name["crate_1"].shape.vertices
    # 25 cm in centimetres, scaled by 2: a 0.5 m cube standing on the floor at (4, 2)
    assert np.allclose(crate.min(axis=0), [3.75, 1.75, 0.0], atol=1e-6)
    assert np.allclose(crate.max(axis=0), [4.25, 2.25, 0.5], atol=1e-6)
    assert world.floor_z == pytest.approx(0.0)
    corners = derive_corner_map(world)
    expected = np.array([[0, 0], [ROOM[0], 0], [ROOM[0], ROOM[1]], [0, ROOM[1]]])
    assert len(corners) == 4
    assert np.abs(np.sort(corners.xy, axis=0) - np.sort(expected, axis=0)).max() <= 0.06  # one 5 cm cell
    assert corners.z == pytest.approx(np.full(4, 3.0))


def test_visual_geometry_on_request(tmp_path):
    meshes = read_sdf_world(_world(tmp_path), geometry="visual")
    (crate,) = [m for name, m in meshes.items() if name.startswith("crate_1")]
    assert crate.extents == pytest.approx([10.0, 10.0, 10.0], rel=0.05)  # its visual is a 5 m sphere


def test_collada_units_and_up_axis_are_honoured(tmp_path):
    _cube_dae(tmp_path / "cm.dae", side=50.0, unit=0.01)
    _cube_dae(tmp_path / "yup.dae", side=2.0, unit=1.0, up="Y_UP")
    assert read_mesh_file(tmp_path / "cm.dae").extents == pytest.approx([0.5, 0.5, 0.5])
    standing = read_mesh_file(tmp_path / "yup.dae")
    assert standing.bounds[0][2] == pytest.approx(0.0) and standing.bounds[1][2] == pytest.approx(2.0)


def test_a_building_tagged_y_up_whose_vertices_stand_z_up_is_not_stood_on_end(tmp_path):
    """A 56 m long wall, 0.18 m thick and 3 m tall, written z up but tagged Y_UP (as published worlds have them)."""
    import trimesh

    wall = trimesh.creation.box(extents=[0.18, 56.0, 3.0])
    wall.apply_translation([0, 0, 1.5])
    text = tmp_path / "seed.dae"
    _cube_dae(text, side=1.0, unit=1.0, up="Y_UP")  # a COLLADA file to put the wall's vertices in
    document = text.read_text()
    positions = " ".join(f"{v:.6f}" for v in wall.vertices.ravel())
    cube = trimesh.creation.box(extents=[1.0, 1.0, 1.0])
    cube.apply_translation([0, 0.5, 0])
    document = document.replace(" ".join(f"{v:.6f}" for v in cube.vertices.ravel()), positions)
    (tmp_path / "wall.dae").write_text(document)
    with pytest.warns(UserWarning, match=r"wall.dae: tagged Y_UP, but turned so it would stand 56.0 m tall"):
        mesh = read_mesh_file(tmp_path / "wall.dae")
    assert mesh.extents == pytest.approx([0.18, 56.0, 3.0], abs=1e-3)


def test_a_world_without_a_ceiling_gets_one_from_ceiling_height(tmp_path):
    source = _world(tmp_path, ceiling=False)
    with pytest.warns(UserWarning, match="no ceiling"):
        bare = load_world(import_world(source, "bare", tmp_path / "maps"))
    assert len(derive_corner_map(bare)) == 0
    roofed = load_world(import_world(source, "roofed", tmp_path / "maps", ceiling_height=2.5))
    corners = derive_corner_map(roofed)
    assert len(corners) == 4 and corners.z == pytest.approx(np.full(4, 2.5))


@pytest.mark.parametrize(
    ("crate_uri", "scale", "message"),
    [
        (
            "model://no_such_model",
            "2 2 2",
            r"room.world: <include> model://no_such_model: model 'no_such_model' not found",
        ),
        ("package://crate", "2 2 2", r"room.world: <include> package://crate: unknown URI scheme"),
        ("model://crate", "2 two 2", r"model.sdf: <scale>: expected numbers"),
        ("model://crate", "500 500 500", r"room.world: object 'crate_1::body::collision' \(clutter\) is 125 m long"),
    ],
)
def test_bad_worlds_are_named_and_leave_nothing_behind(tmp_path, crate_uri, scale, message):
    source = _world(tmp_path, crate_uri=crate_uri, scale=scale)
    with pytest.raises(MapFileError, match=message):
        import_world(source, "bad", tmp_path / "maps", strict=True)
    assert not (tmp_path / "maps" / "bad").exists()


def test_name_rules_match_whole_words_and_the_last_specific_rule_wins():
    defaults = [
        ("*", SemanticClass.CLUTTER),
        ("ceiling", SemanticClass.CEILING),
        ("floor", SemanticClass.FLOOR),
        ("wall", SemanticClass.WALL),
    ]
    assert classify("HouseWallB_01_001::link", defaults) == SemanticClass.WALL
    assert classify("hospital_floor_01_walls_1", defaults) == SemanticClass.WALL
    assert classify("FloorB_01", defaults) == SemanticClass.FLOOR
    assert classify("Wallpaper_roll", defaults) == SemanticClass.CLUTTER
    assert classify("CEILING_LAMP", defaults) == SemanticClass.CEILING
    assert classify("CEILING_LAMP", [*defaults, ("lamp", SemanticClass.CLUTTER)]) == SemanticClass.CLUTTER
    assert classify("Cealing_004", [("Cealing*", SemanticClass.CEILING), ("*", SemanticClass.CLUTTER)]) == (
        SemanticClass.CEILING
    )
    from pimm_env.importers.world_import import DEFAULT_MESH_RULES

    shipped = [(r["match"], SemanticClass[r["class"].upper()]) for r in DEFAULT_MESH_RULES]
    assert classify("hospital_floor_01_ceiling_1", shipped) == SemanticClass.CEILING  # the more specific wins
    assert classify("hospital_floor_01_walls_1", shipped) == SemanticClass.WALL


def test_a_loop_of_includes_is_one_error_naming_it(tmp_path):
    models = tmp_path / "models"
    for name, other in (("a", "b"), ("b", "a")):  # a includes b, b includes a
        (models / name).mkdir(parents=True)
        (models / name / "model.config").write_text(f"<model><name>{name}</name><sdf>model.sdf</sdf></model>")
        (models / name / "model.sdf").write_text(
            f"<sdf version='1.6'><model name='{name}'><include><uri>model://{other}</uri></include></model></sdf>"
        )
    world = tmp_path / "loop.world"
    world.write_text("<sdf version='1.6'><world name='w'><include><uri>model://a</uri></include></world></sdf>")
    with pytest.raises(MapFileError, match=r"<include> model://a is a loop of includes \(.*a/model.sdf -> .*b/model"):
        read_sdf_world(world, model_paths=[models])


def test_missing_models_are_left_out_and_counted_and_uris_resolve_as_gazebo_resolves_them(tmp_path, monkeypatch):
    """A model not found is left out with a warning (Gazebo loads the rest); a mesh named in another case is
    found and said; ``file://models/...`` resolves against the world's folder from anywhere."""
    source = _world(tmp_path, crate_uri="model://no_such_model")
    with pytest.warns(UserWarning, match=r"1 model\(s\) or mesh\(es\) not found, left out .*model://no_such_model"):
        meshes = read_sdf_world(source)
    assert not any("crate" in name for name in meshes) and any("column" in name for name in meshes)
    source = _world(tmp_path)
    sdf = tmp_path / "models" / "crate" / "model.sdf"
    sdf.write_text(sdf.read_text().replace("model://crate/meshes/crate.dae", "file://models/crate/meshes/Crate.DAE"))
    monkeypatch.chdir(tmp_path.parent)  # not the world's folder
    with pytest.warns(UserWarning, match=r"differing in case: file://models/crate/meshes/Crate.DAE: .*crate.dae"):
        meshes = read_sdf_world(source)
    assert any("crate" in name for name in meshes)
