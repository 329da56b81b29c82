"""The iiLab environment (``pimm/IILab-v1``): the thesis's building, robot and sensors as a Gymnasium env."""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np

from pimm_env.envs.base_env import LidarRobotEnv
from pimm_env.envs.sim_config import SimConfig, with_sensors
from pimm_env.errors import EnvError
from pimm_env.world.files import World


class IILabEnv(LidarRobotEnv):
    """
    ## Description

    A differential-drive robot with wheel encoders, a 3D LiDAR and a 2D LiDAR in the iiLab building
    (thesis section 3.1): large hall A, corridor C and cluttered area B, with ceilings at 3.91, 7.91 and
    3.01 m. The environment serves localization: it carries no task, and a localizer consumes its
    observations while an evaluator compares the estimates with ``info["true_pose"]``.

    ## Action Space

    ``Box(2,)`` float32: linear velocity in [-1, 1] m/s and angular velocity in [-2, 2] rad/s, like a
    ``cmd_vel`` Twist. Out-of-range actions are clipped; non-finite actions raise ``ValueError``.

    ## Observation Space

    | key          | shape        | dtype   | meaning                                                        |
    |--------------|--------------|---------|----------------------------------------------------------------|
    | `odom`       | (3,)         | float32 | wheel-odometry pose (x, y, theta) in the odometry frame        |
    | `cloud`      | (14400, 3)   | float32 | 3D LiDAR points in the sensor frame (40 layers x 360), padded  |
    | `cloud_mask` | (14400,)     | int8    | 1 where `cloud` holds a real return                            |
    | `scan`       | (360,)       | float32 | 2D LiDAR ranges from -pi counter-clockwise, no return = 10 m   |
    | `time`       | (1,)         | float64 | sim time of this observation (s)                               |
    | `cloud_time` | (1,)         | float64 | sim time of the 3D scan carried in `cloud`                     |
    | `scan_time`  | (1,)         | float64 | sim time of the 2D scan carried in `scan`                      |

    Scans come at 10 Hz while the control step is 32 ms, so most observations repeat the last scan; a
    localizer tells a fresh one by its time. Ground truth is never in the observation.

    ## Rewards

    None: the reward is always 0.0.

    ## Starting State

    A uniformly random free pose (at least 0.15 m more than the robot's radius from any obstacle), with
    odometry at (0, 0, 0). ``options={"pose": [x, y, theta]}`` places the robot; a pose inside an obstacle
    or outside the map raises ``ValueError``. ``options={"kidnap": True}`` (random free pose) or
    ``options={"kidnap": [x, y, theta]}`` teleports the robot without resetting time, wheels or odometry.

    ## Episode End

    Terminates when the robot touches an obstacle (unless ``terminate_on_collision=False``); truncated by
    the registered ``max_episode_steps`` (20 000 steps, 640 s).

    ## Arguments

    | argument                 | default   | meaning                                                         |
    |--------------------------|-----------|-----------------------------------------------------------------|
    | `world`                  | `"iilab"` | world name under `maps/`, a world file, or a `World`            |
    | `config`                 | defaults  | `SimConfig`: robot, 3D/2D LiDAR settings, ray caster            |
    | `sensors`                | `None`    | LiDAR presets by name (`"hokuyo-utm30lx"`; see `sim/sensors.py`) |
    | `render_mode`            | `None`    | `"rgb_array"`: top-down map, robot and current scans            |
    | `terminate_on_collision` | `True`    | end the episode when the body touches an obstacle               |
    | `walkers`                | `0`       | people walking about (clutter; not in the maps; see sim/movers) |
    | `unmapped`               | `0`       | furniture along the walls that the derived maps do not have     |

    `info` holds `true_pose` (map frame), `labels` (semantic class per cloud point, -1 for no return),
    `collision`, `fresh_cloud`, `fresh_scan`, `area` (A, B, C or None) and `travelled` (m); with walkers or
    unmapped furniture, `walkers` and `unmapped`: one row per box, (x, y, yaw, length, width, height). Both
    are drawn anew at every full reset from its seed; a kidnap keeps them.

    ## Version History

    * v1: the same seed gives other observations than v0. Each LiDAR draws its noise from a stream of its own
      (turning the 3D LiDAR off no longer changes the 2D scans); Embree (Open3D) is the default ray caster
      (it agrees with pybullet on 99.9 % of hits, 99 % of ranges within 1 cm, tests/test_raycast.py); walkers and
      unmapped furniture (``walkers``, ``unmapped``, drawn from a stream of their own); LiDAR presets
      (``sensors``) and the 3D LiDAR's mount pose; ``render_fps`` follows the control step (31 Hz); no
      pybullet scene is built unless ``config.ray_caster == "bullet"``; pickling keeps walkers, furniture,
      faults and sensors.
    * v0: initial version (retired: not registered, since this code no longer reproduces it).
    """

    def __init__(
        self,
        world: str | World = "iilab",
        config: SimConfig | None = None,
        render_mode: str | None = None,
        terminate_on_collision: bool = True,
        sensors: str | None = None,
        walkers: int | None = None,
        unmapped: int | None = None,
    ) -> None:
        if sensors is not None:
            config = with_sensors(config or SimConfig(), sensors)
        for name, count in (("walkers", walkers), ("unmapped", unmapped)):
            if count is not None and (not isinstance(count, int | np.integer) or count < 0):
                raise EnvError(f"{name} must be a whole number >= 0, got {count!r}")
        if walkers is not None:
            config = replace(config or SimConfig(), walkers=int(walkers))
        if unmapped is not None:
            config = replace(config or SimConfig(), unmapped=int(unmapped))
        super().__init__(world=world, config=config, render_mode=render_mode)
        self._terminate_on_collision = terminate_on_collision

    def _terminated(self, info: dict[str, Any]) -> bool:
        return self._terminate_on_collision and info["collision"]
