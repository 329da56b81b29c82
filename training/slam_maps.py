"""Point-cloud maps of generated buildings made the way SLAM makes them, with the trajectory SLAM writes beside
its map (cloud_maps.py imports and scores them).

A SLAM-like map (:func:`slam_like_cloud`): the simulated 3D LiDAR's clouds along every route of the building
(rooms off the routes are seen only through their doorways, so the map has holes), laid at poses that drift a
few centimetres and a few tenths of a degree from the truth (a smooth error of its own period on each axis), with
people walking through while mapping (their ghosts are in the map) and the building's furniture, thinned to 5 cm
voxels. Its trajectory is the poses the clouds were laid at, drift included: SLAM's own estimate, in its map's
frame.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

import numpy as np


@dataclass(frozen=True)
class SlamLike:
    """How the SLAM-like maps are made (ours: the few centimetres of error a LiDAR SLAM map carries indoors)."""

    walkers: int = 3  # people walking about while the map was made
    pose_error_m: float = 0.03  # the largest drift of the mapping poses in x and y
    yaw_error_deg: float = 0.3  # ... and in heading
    every: int = 2  # one cloud in this many (a SLAM keyframe rate)
    voxel_m: float = 0.05  # the map's voxel filter


@dataclass(frozen=True)
class SlamLikeMap:
    """What a SLAM run over a building leaves: its point-cloud map and its trajectory; and the truth beside them."""

    points: np.ndarray  # (N, 3) the map, world frame, one point a voxel
    true_poses: np.ndarray  # (M, 3) where each of its clouds was taken
    times: np.ndarray  # (M,) s, the routes one after another
    poses: np.ndarray  # (M, 3) where SLAM laid each cloud (the truth and its drift): the trajectory it writes


def slam_like_cloud(world: Any, seed: int, config: SlamLike = SlamLike()) -> SlamLikeMap:
    """A SLAM-like point-cloud map of ``world`` (loaded) from its routes (see the module), with its trajectory."""
    from pimm_env.bags.cloud_map import laid_at, thinned
    from pimm_env.driving.rollout import run
    from pimm_env.driving.scenarios import load_scenarios
    from pimm_env.envs.iilab_env import IILabEnv
    from pimm_env.envs.sim_config import SimConfig

    rng = np.random.default_rng(seed)
    env = IILabEnv(world=world, config=replace(SimConfig(), walkers=config.walkers), terminate_on_collision=False)
    lidar = env.config.lidar3d
    clouds: list[np.ndarray] = []
    poses: list[np.ndarray] = []
    laid: list[np.ndarray] = []
    times: list[float] = []
    scale = np.array([config.pose_error_m, config.pose_error_m, np.radians(config.yaw_error_deg)])
    try:
        for k, scenario in enumerate(s for s in load_scenarios(world).values() if s.kidnap_to is None):
            amplitude = scale * rng.uniform(0.5, 1.0, 3)
            period, phase = rng.uniform(20.0, 60.0, 3), rng.uniform(0.0, 2 * np.pi, 3)
            fresh = [0]
            start = times[-1] + 1.0 if times else 0.0  # each route's clock after the last one's

            def lay(
                obs: dict[str, Any],
                info: dict[str, Any],
                amplitude=amplitude,
                period=period,
                phase=phase,
                fresh=fresh,
                start=start,
            ) -> None:
                if not info.get("fresh_cloud"):
                    return
                fresh[0] += 1
                if fresh[0] % config.every:
                    return
                drift = amplitude * np.sin(2 * np.pi * float(obs["time"][0]) / period + phase)
                poses.append(np.asarray(info["true_pose"], dtype=float))
                laid.append(poses[-1] + drift)
                times.append(start + float(obs["time"][0]))
                clouds.append(laid_at(obs["cloud"], obs["cloud_mask"], laid[-1], lidar))

            run(scenario, seed=seed + k, env=env, on_step=lay)
    finally:
        env.close()
    return SlamLikeMap(thinned(np.vstack(clouds), config.voxel_m), np.array(poses), np.array(times), np.array(laid))
