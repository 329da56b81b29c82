"""Ceilings of any shape give the corners under them: a closed slab, a one-sided plane, two heights."""

import numpy as np
import pytest

from pimm_env.importers.world_import import import_world
from pimm_env.mapping.ceilings import ceiling_levels
from pimm_env.mapping.corner_map import derive_corner_map
from pimm_env.world.files import load_world


def _box(lo, hi):
    import trimesh

    return trimesh.creation.box(bounds=np.array([lo, hi], dtype=float))


def _plane(z: float, x0: float, x1: float, y0: float, y1: float, facing_up: bool):
    import trimesh

    faces = [[0, 1, 2], [0, 2, 3]] if facing_up else [[0, 2, 1], [0, 3, 2]]
    return trimesh.Trimesh([[x0, y0, z], [x1, y0, z], [x1, y1, z], [x0, y1, z]], faces, process=False)


def _two_rooms(tmp_path, ceilings: dict):
    """Rooms 0..4 and 4.2..8 (x) by 0..4 (y), walls 0.2 thick and 4 m tall (hollow mesh shells)."""
    import trimesh

    scene = trimesh.Scene()
    scene.add_geometry(_box([-0.5, -0.5, -0.1], [8.7, 4.7, 0.0]), node_name="Floor")
    walls = [
        ([-0.2, -0.2, 0], [8.2, 0, 4]),
        ([-0.2, 4, 0], [8.2, 4.2, 4]),
        ([-0.2, 0, 0], [0, 4, 4]),
        ([4.0, 0, 0], [4.2, 4, 4]),
        ([8.0, 0, 0], [8.2, 4, 4]),
    ]
    for k, (lo, hi) in enumerate(walls):
        scene.add_geometry(_box(lo, hi), node_name=f"Wall_{k}")
    for name, mesh in ceilings.items():
        scene.add_geometry(mesh, node_name=name)
    source = tmp_path / "rooms.glb"
    scene.export(source)
    return load_world(import_world(source, "rooms", tmp_path / "maps"))


@pytest.mark.parametrize(
    "ceiling",
    [
        {"Ceiling_slab": _box([-0.2, -0.2, 3.0], [8.2, 4.2, 3.2])},
        {"Ceiling_plane": _plane(3.0, -0.2, 8.2, -0.2, 4.2, facing_up=True)},
        {"Ceiling_plane": _plane(3.0, -0.2, 8.2, -0.2, 4.2, facing_up=False)},
    ],
    ids=["closed slab", "plane facing up", "plane facing down"],
)
def test_a_ceiling_of_any_shape_covers_every_room_corner(tmp_path, ceiling):
    world = _two_rooms(tmp_path, ceiling)
    assert ceiling_levels(world) == [3.0]
    corners = derive_corner_map(world)
    assert len(corners) == 8  # four per room, none inside the hollow walls
    assert corners.z == pytest.approx(np.full(8, 3.0))


def test_two_ceiling_heights_give_each_room_its_own(tmp_path):
    world = _two_rooms(
        tmp_path,
        {
            "Ceiling_low": _box([-0.2, -0.2, 2.5], [4.1, 4.2, 2.6]),
            "Ceiling_high": _box([4.1, -0.2, 3.5], [8.2, 4.2, 3.6]),
        },
    )
    assert ceiling_levels(world) == [2.5, 3.5]
    corners = derive_corner_map(world)
    low = corners.xy[np.isclose(corners.z, 2.5)]
    high = corners.xy[np.isclose(corners.z, 3.5)]
    assert len(low) == 4 and np.all(low[:, 0] < 4.1)
    assert len(high) == 4 and np.all(high[:, 0] > 4.1)


def _slope(x0: float, x1: float, z0: float, z1: float, y0: float = -0.2, y1: float = 4.2):
    """A plane sloping from height z0 at x0 to z1 at x1."""
    import trimesh

    vertices = [[x0, y0, z0], [x1, y0, z1], [x1, y1, z1], [x0, y1, z0]]
    return trimesh.Trimesh(vertices, [[0, 2, 1], [0, 3, 2]], process=False)


@pytest.mark.parametrize(
    "ceiling, low",
    [
        # a flat room beside one under a 20 deg slope, and a gable roof over both (ridge on the middle wall)
        ({"Ceiling_flat": _box([-0.2, -0.2, 3.0], [4.1, 4.2, 3.2]), "Ceiling_slope": _slope(4.1, 8.2, 2.4, 3.9)}, 2.4),
        ({"Ceiling_west": _slope(-0.2, 4.1, 2.4, 3.9), "Ceiling_east": _slope(4.1, 8.2, 3.9, 2.4)}, 2.4),
    ],
    ids=["flat beside sloped", "gable"],
)
def test_walls_under_a_sloped_ceiling_give_their_corners_once(tmp_path, ceiling, low):
    world = _two_rooms(tmp_path, ceiling)
    assert min(ceiling_levels(world)) == pytest.approx(low)  # a slope counts from its lowest point
    corners = derive_corner_map(world)
    assert len(corners) == 8  # four per room, each once though a slope spans many heights
    assert np.all(corners.z[corners.xy[:, 0] > 4.1] == pytest.approx(low))


def test_a_corner_under_two_ceilings_of_nearly_one_height_is_one_corner(tmp_path):
    # the east room's ceiling 4 cm above the west room's: the middle wall's corners are found at both heights
    world = _two_rooms(
        tmp_path,
        {
            "Ceiling_west": _box([-0.2, -0.2, 3.0], [4.15, 4.2, 3.1]),
            "Ceiling_east": _box([4.05, -0.2, 3.04], [8.2, 4.2, 3.14]),
        },
    )
    corners = derive_corner_map(world)
    assert len(corners) == 8
    assert len({(round(x, 2), round(y, 2)) for x, y in corners.xy}) == 8


def test_walls_at_a_slant_under_a_mesh_ceiling_give_the_corners_of_their_outline(tmp_path):
    """A point-cloud import's kind of world: box walls at any angle beside a mesh ceiling at two heights."""
    import yaml

    turn = np.radians(20.0)
    along, across = np.array([np.cos(turn), np.sin(turn)]), np.array([-np.sin(turn), np.cos(turn)])
    walls = []
    for k, (centre, length, yaw) in enumerate(
        [(2 * along - 0.1 * across, 4.4, turn), (2 * along + 4.1 * across, 4.4, turn),
         (-0.1 * along + 2 * across, 4.4, turn + np.pi / 2), (4.1 * along + 2 * across, 4.4, turn + np.pi / 2)]
    ):  # fmt: skip
        box = {"center": [*np.round(centre, 4).tolist(), 1.5], "size": [length, 0.2, 3.0], "yaw": float(yaw)}
        walls.append({"name": f"wall_{k}", "class": "wall", "box": box})
    room = np.array([[0, 0], [4, 0], [4, 4], [0, 4]]) @ np.array([along, across])
    low = _plane(2.5, -2.0, 1.5, -1.0, 6.0, facing_up=False)  # the room's west part lower: two heights
    high = _plane(3.0, 1.5, 5.0, -1.0, 6.0, facing_up=False)
    import trimesh

    scene = trimesh.Scene()
    scene.add_geometry(_box([-2, -2, -0.1], [6, 7, 0]), node_name="floor")
    scene.add_geometry(trimesh.util.concatenate([low, high]), node_name="ceiling")
    scene.export(tmp_path / "room.glb")
    spec = {
        "format": "pimm-mesh-world/1", "name": "slanted", "mesh": "room.glb", "up_axis": "z",
        "rules": [{"match": "*", "class": "clutter"}, {"match": "floor", "class": "floor"},
                  {"match": "ceiling", "class": "ceiling"}],
        "areas": {"room": room.round(4).tolist()}, "elements": walls,
    }  # fmt: skip
    (tmp_path / "world.yaml").write_text(yaml.safe_dump(spec))
    corners = derive_corner_map(load_world(tmp_path / "world.yaml"))
    assert len(corners) == 4
    gaps = np.hypot(*(corners.xy[:, None, :] - room[None, :, :]).transpose(2, 0, 1)).min(axis=0)
    assert gaps.max() < 0.02
    west = room[:, 0] < 1.5  # each corner at the height of the ceiling over it
    order = np.argmin(np.hypot(*(corners.xy[:, None, :] - room[None, :, :]).transpose(2, 0, 1)), axis=0)
    assert np.allclose(corners.z[order], np.where(west, 2.5, 3.0))


def test_a_mesh_ceiling_drawn_a_little_short_of_the_walls_still_covers_their_corners(tmp_path):
    """A point-cloud import's ceiling is drawn column by column: beside a wall it can stop a cell or two short."""
    import shapely
    import trimesh
    import yaml
    from shapely.geometry import Polygon

    turn = np.radians(20.0)
    along, across = np.array([np.cos(turn), np.sin(turn)]), np.array([-np.sin(turn), np.cos(turn)])
    room = np.array([[0, 0], [4, 0], [4, 4], [0, 4]]) @ np.array([along, across])
    walls = Polygon([tuple(p) for p in room]).buffer(0.2, join_style="mitre").difference(Polygon(room))
    short = np.asarray(shapely.orient_polygons(Polygon(room).buffer(-0.08, join_style="mitre")).exterior.coords)[:4]
    lid = trimesh.Trimesh(np.column_stack([short, np.full(4, 2.5)]), [[0, 2, 1], [0, 3, 2]], process=False)
    scene = trimesh.Scene()
    scene.add_geometry(_box([-3, -1, -0.1], [5, 6, 0]), node_name="floor")
    scene.add_geometry(lid, node_name="ceiling")
    scene.export(tmp_path / "room.glb")
    prism = {"outline": np.asarray(walls.exterior.coords)[:-1].round(4).tolist(),
             "holes": [np.asarray(walls.interiors[0].coords)[:-1].round(4).tolist()], "z": [0.0, 2.5]}  # fmt: skip
    spec = {
        "format": "pimm-mesh-world/1", "name": "short", "mesh": "room.glb", "up_axis": "z",
        "rules": [{"match": "*", "class": "clutter"}, {"match": "floor", "class": "floor"},
                  {"match": "ceiling", "class": "ceiling"}],
        "areas": {"room": room.round(4).tolist()}, "elements": [{"name": "walls", "class": "wall", "prism": prism}],
    }  # fmt: skip
    (tmp_path / "world.yaml").write_text(yaml.safe_dump(spec))
    corners = derive_corner_map(load_world(tmp_path / "world.yaml"))
    assert len(corners) == 4 and np.allclose(corners.z, 2.5)
    assert np.hypot(*(corners.xy[:, None, :] - room[None, :, :]).transpose(2, 0, 1)).min(axis=0).max() < 0.02
