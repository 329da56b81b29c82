"""A point-cloud map from a bag: its 3D clouds laid at its true poses and thinned to one point per voxel, the
kind of file a robot's SLAM writes (``world import`` reads it back as a building)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from pimm_env.bags.read import read_steps
from pimm_env.errors import BagError
from pimm_env.geometry import compose
from pimm_env.sim.lidar import Lidar3DConfig, to_robot_frame

#: clouds laid before the map is thinned again (bounds the memory a long bag takes)
THIN_EVERY = 50


def cloud_map_from_bag(
    bag: Path, topics, lidar2d, lidar3d: Lidar3DConfig, voxel_m: float = 0.05
) -> tuple[np.ndarray, int]:
    """The bag's clouds at its true poses, one point (the mean) per ``voxel_m`` voxel, and how many clouds
    (``lidar2d``: the bag's 2D layout, None where it has no scans)."""
    import open3d as o3d

    from pimm_env.sim.lidar import Lidar2DConfig

    taken, pending, clouds = np.zeros((0, 3)), [], 0
    for step in read_steps(Path(bag), topics, lidar2d or Lidar2DConfig(), lidar3d):
        if not (step.fresh_cloud and step.true_pose is not None):
            continue
        cloud, mask = np.asarray(step.obs["cloud"], dtype=float), np.asarray(step.obs["cloud_mask"], dtype=bool)
        points = to_robot_frame(cloud[mask], lidar3d)
        planar = compose(step.true_pose, np.column_stack([points[:, :2], np.zeros(len(points))]))[:, :2]
        pending.append(np.column_stack([planar, points[:, 2] + lidar3d.height]))
        clouds += 1
        if len(pending) >= THIN_EVERY:
            taken, pending = _thin(np.vstack([taken, *pending]), voxel_m, o3d), []
    if not clouds:
        raise BagError(f"{bag}: no cloud ({topics.points}) arrived with a true pose ({topics.truth}): no map to build")
    return _thin(np.vstack([taken, *pending]), voxel_m, o3d), clouds


def _thin(points: np.ndarray, voxel_m: float, o3d) -> np.ndarray:
    cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(points))
    return np.asarray(cloud.voxel_down_sample(voxel_m).points)
