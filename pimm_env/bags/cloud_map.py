"""A point-cloud map from a bag: its 3D clouds laid at its true poses and thinned to one point per voxel, with
the poses they were laid at: the two files a robot's SLAM writes (``world import`` reads them back as a
building)."""

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
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The bag's clouds at its true poses, one point (the mean) per ``voxel_m`` voxel; and the time (C,) and
    pose (C, 3) each of its C clouds was laid at: the map's trajectory (``lidar2d``: the bag's 2D layout, None
    where it has no scans)."""

    from pimm_env.sim.lidar import Lidar2DConfig

    taken, pending, times, poses = np.zeros((0, 3)), [], [], []
    for step in read_steps(Path(bag), topics, lidar2d or Lidar2DConfig(), lidar3d):
        if not (step.fresh_cloud and step.true_pose is not None):
            continue
        pending.append(laid_at(step.obs["cloud"], step.obs["cloud_mask"], step.true_pose, lidar3d))
        times.append(float(step.obs["time"][0]))
        poses.append(np.asarray(step.true_pose, dtype=float))
        if len(pending) >= THIN_EVERY:
            taken, pending = thinned(np.vstack([taken, *pending]), voxel_m), []
    if not poses:
        raise BagError(f"{bag}: no cloud ({topics.points}) arrived with a true pose ({topics.truth}): no map to build")
    return thinned(np.vstack([taken, *pending]), voxel_m), np.array(times), np.array(poses)


def laid_at(cloud: np.ndarray, mask: np.ndarray, pose: np.ndarray, lidar3d: Lidar3DConfig) -> np.ndarray:
    """A cloud's returns (sensor frame, ``mask``: which are returns) in the map frame, the robot at ``pose``
    (x, y, heading), z above the floor."""
    points = to_robot_frame(np.asarray(cloud, dtype=float)[np.asarray(mask, dtype=bool)], lidar3d)
    planar = compose(pose, np.column_stack([points[:, :2], np.zeros(len(points))]))[:, :2]
    return np.column_stack([planar, points[:, 2] + lidar3d.height])


def thinned(points: np.ndarray, voxel_m: float) -> np.ndarray:
    """One point (the mean) per ``voxel_m`` voxel, as a SLAM map's voxel filter keeps."""
    import open3d as o3d

    cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(points))
    return np.asarray(cloud.voxel_down_sample(voxel_m).points)
