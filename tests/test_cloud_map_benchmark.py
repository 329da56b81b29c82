import numpy as np

from pimm_env.mapping.corner_map import CornerMap
from pimm_env.world.grid import GridSpec
from training.cloud_maps import MATCH_M, corner_figures, in_sight, pooled_times, seen_cells


def test_rays_from_the_mapping_poses_see_the_faces_in_front_of_them_not_the_rooms_behind():
    grid = GridSpec(origin=(0.0, 0.0), resolution=0.05, shape=(80, 160))  # 8 m x 4 m
    walls = np.zeros(grid.shape, dtype=bool)
    walls[[0, -1], :] = walls[:, [0, -1]] = True
    walls[:, 80:82] = True  # a wall at x = 4 m between two rooms, no door
    seen = seen_cells(walls, grid, np.array([[1.0, 2.0, 0.0], [2.0, 2.0, 0.0]]), reach_m=10.0)
    assert seen[1:-1, 80].sum() > 60 and not seen[1:-1, 81].any()  # the near face, not its back
    assert not seen[1:-1, 82:].any()  # nothing of the room behind it


def test_a_corner_is_in_sight_from_its_room_not_from_behind_a_thin_wall():
    """A 10 cm wall at x = 4.0-4.1 m between two rooms, a door at y = 3-4 m; the mapping poses in the left room.
    The corners of the right room beside the wall lie 10 cm from the wall cells seen from the left, but no ray
    reaches them; its far corner is seen through the door."""
    grid = GridSpec(origin=(0.0, 0.0), resolution=0.05, shape=(100, 200))  # 10 m x 5 m
    walls = np.zeros(grid.shape, dtype=bool)
    walls[[0, -1], :] = walls[:, [0, -1]] = True
    walls[:60, 80:82] = True  # the wall, up to the door at y = 3 m
    poses = np.column_stack([np.linspace(1.0, 3.0, 9), np.full(9, 3.5), np.zeros(9)])
    corners = np.array([[0.05, 0.05], [3.95, 0.05], [4.15, 0.05], [4.15, 2.0], [9.95, 4.95]])
    assert in_sight(corners, walls, grid, poses, 10.0).tolist() == [True, True, False, False, True]


def test_corners_are_matched_within_ten_centimetres_and_the_rest_counted_both_ways():
    """A found corner is not the building's only where no walls of it meet within 10 cm (``there``: with the
    faces' slack)."""

    def corners(xy):
        xy = np.asarray(xy, dtype=float)
        return CornerMap(xy, np.full(len(xy), 3.0), np.zeros(len(xy)))

    truth = corners([[0, 0], [4, 0], [4, 3], [0, 3]])
    found = corners([[0.05, 0.0], [4.0, 0.0 + MATCH_M + 0.05], [2.0, 1.5]])
    figures = corner_figures(truth, found, np.array([True, True, False, False]))
    assert figures["recall_seen"] == 0.5 and figures["recall_all"] == 0.25
    assert figures["false"] == 2 / 3 and figures["seen"] == 2
    stub = corners([[0, 0], [4, 0], [4, 3], [0, 3], [4.0, MATCH_M + 0.1]])  # walls meeting with a shorter face
    with_stub = corner_figures(truth, found, np.array([True, True, False, False]), stub)
    assert with_stub["false"] == 1 / 3 and with_stub["recall_seen"] == 0.5  # found ones only: recall is the truth's
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


def test_the_pooled_times_take_every_buildings_trials_and_say_how_sure_the_ratio_is():
    rows = {
        "gen-1": {"own_maps": {"times_s": [2.0, 2.0, 4.0]}, "cloud_maps": {"times_s": [3.0, 3.0, 6.0]}},
        "gen-2": {"own_maps": {"times_s": [2.0, 4.0]}, "cloud_maps": {"times_s": [3.0, 6.0]}},
    }
    line = pooled_times(rows)
    assert "2.0 s with their own maps (5 trials), 3.0 s with the imported ones (5)" in line
    assert "1.50 times as long" in line
    low, high = (float(v) for v in line.split("interval ")[1].rstrip(").").split("-"))
    assert low <= 1.5 <= high and high > low  # resampled medians of 2 / 4 and 3 / 6: anywhere from 0.75 to 3
    assert line == pooled_times(rows)  # seeded
    assert pooled_times({"gen-1": {"own_maps": {"times_s": [2.0]}}}) == ""  # no imported maps' trials
