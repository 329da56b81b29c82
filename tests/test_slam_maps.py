"""SLAM-like point-cloud maps (training/slam_maps.py): a map and the trajectory it was laid along."""

import numpy as np
import pytest
import yaml

from training.slam_maps import SlamLike, slam_like_cloud

TWO_ROUTES = """
format: pimm-scenarios/1
scenarios:
  there:
    start: [1.0, 1.0, 0.0]
    waypoints: [[1.0, 1.0], [3.0, 1.0]]
    speed: 0.5
  back:
    start: [3.0, 3.0, 3.1416]
    waypoints: [[3.0, 3.0], [1.0, 3.0]]
    speed: 0.5
"""


@pytest.mark.expensive
def test_a_slam_like_map_comes_with_the_trajectory_it_was_laid_along_and_imports_with_it(room_file, tmp_path):
    from pimm_agents.results.tum import write_tum
    from pimm_env.clouds.pcd import write_pcd
    from pimm_env.importers.world_import import import_world
    from pimm_env.mapping.derived_maps import ensure_derived_maps
    from pimm_env.world.files import load_world

    (room_file.parent / "scenarios.yaml").write_text(TWO_ROUTES)
    ensure_derived_maps(load_world(room_file))
    slam = slam_like_cloud(load_world(room_file), seed=0, config=SlamLike(walkers=1))
    assert len(slam.times) == len(slam.poses) == len(slam.true_poses) > 10
    assert np.all(np.diff(slam.times) > 0)  # the second route's clock runs on after the first's
    drift = np.abs(slam.poses - slam.true_poses)
    assert 0 < drift[:, :2].max() <= 0.03 and drift[:, 2].max() <= np.radians(0.3)  # SlamLike's drift, no more
    path = write_tum(tmp_path / "room.tum", slam.times, slam.poses)
    world = import_world(write_pcd(tmp_path / "room.pcd", slam.points), "room_map", tmp_path / "maps", trajectory=path)
    assert yaml.safe_load(world.read_text())["cloud_map"]["trajectory"]["poses"] == len(slam.poses)
