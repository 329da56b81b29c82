"""The env's action and observation spaces for a ``SimConfig``'s robot and LiDARs (ARCHITECTURE.md's contract),
shared by the simulator and the bag replay env."""

from __future__ import annotations

import numpy as np
from gymnasium import spaces

from pimm_env.envs.sim_config import SimConfig

MAX_TIME = 1.0e6  # s; bound of the time fields of the observation
MAX_ODOM = 1.0e4  # m; bound of the odometry position


def action_space(config: SimConfig) -> spaces.Box:
    """``cmd_vel``: linear and angular velocity (m/s, rad/s) within the robot's limits."""
    r = config.robot
    return spaces.Box(
        low=np.array([-r.max_linear, -r.max_angular], dtype=np.float32),
        high=np.array([r.max_linear, r.max_angular], dtype=np.float32),
        dtype=np.float32,
    )


def observation_space(config: SimConfig) -> spaces.Dict:
    """The observation's keys and fixed shapes for these LiDARs (ARCHITECTURE.md's contract)."""
    l3, l2 = config.lidar3d, config.lidar2d
    n = l3.num_points
    time_box = spaces.Box(low=np.float64(0.0), high=np.float64(MAX_TIME), shape=(1,), dtype=np.float64)
    return spaces.Dict(
        {
            "odom": spaces.Box(
                low=np.array([-MAX_ODOM, -MAX_ODOM, -np.pi], dtype=np.float32),
                high=np.array([MAX_ODOM, MAX_ODOM, np.pi], dtype=np.float32),
                dtype=np.float32,
            ),
            "cloud": spaces.Box(np.float32(-l3.max_range), np.float32(l3.max_range), (n, 3), np.float32),
            "cloud_mask": spaces.MultiBinary(n),
            "scan": spaces.Box(np.float32(0.0), np.float32(l2.max_range), (l2.beams,), np.float32),
            "time": time_box,
            "cloud_time": time_box,
            "scan_time": time_box,
        }
    )
