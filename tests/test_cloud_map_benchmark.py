import numpy as np

from pimm_env.mapping.corner_map import CornerMap
from pimm_env.world.grid import GridSpec
from training.cloud_maps import MATCH_M, corner_figures, seen_cells


def test_rays_from_the_mapping_poses_see_the_faces_in_front_of_them_not_the_rooms_behind():
    grid = GridSpec(origin=(0.0, 0.0), resolution=0.05, shape=(80, 160))  # 8 m x 4 m
    walls = np.zeros(grid.shape, dtype=bool)
    walls[[0, -1], :] = walls[:, [0, -1]] = True
    walls[:, 80:82] = True  # a wall at x = 4 m between two rooms, no door
    seen = seen_cells(walls, grid, np.array([[1.0, 2.0, 0.0], [2.0, 2.0, 0.0]]), reach_m=10.0)
    assert seen[1:-1, 80].sum() > 60 and not seen[1:-1, 81].any()  # the near face, not its back
    assert not seen[1:-1, 82:].any()  # nothing of the room behind it


def test_corners_are_matched_within_ten_centimetres_and_the_rest_counted_both_ways():
    def corners(xy):
        xy = np.asarray(xy, dtype=float)
        return CornerMap(xy, np.full(len(xy), 3.0), np.zeros(len(xy)))

    truth = corners([[0, 0], [4, 0], [4, 3], [0, 3]])
    found = corners([[0.05, 0.0], [4.0, 0.0 + MATCH_M + 0.05], [2.0, 1.5]])
    figures = corner_figures(truth, found, np.array([True, True, False, False]))
    assert figures["recall_seen"] == 0.5 and figures["recall_all"] == 0.25
    assert figures["false"] == 2 / 3 and figures["seen"] == 2
    none = corner_figures(truth, corners(np.zeros((0, 2))), np.array([True, True, False, False]))
    assert (none["seen"], none["found"], none["recall_seen"], none["false"]) == (2, 0, 0.0, 0.0)


def test_the_figure_shows_the_map_beside_its_import_over_the_building(room_file, tmp_path):
    from pimm_env.clouds.pcd import write_pcd
    from pimm_env.importers.world_import import import_world
    from pimm_env.mapping.derived_maps import ensure_derived_maps
    from pimm_env.world.files import load_world
    from tests.test_cloud_map import slam_like_room
    from training.cloud_maps import cloud_map_figure

    points = slam_like_room(np.random.default_rng(0))
    imported = import_world(write_pcd(tmp_path / "room.pcd", points), "room_map", tmp_path / "maps")
    for world in (room_file, imported):
        ensure_derived_maps(load_world(world))
    figure = cloud_map_figure(points, room_file, imported, tmp_path / "room.png")
    assert figure.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and figure.stat().st_size > 20_000
