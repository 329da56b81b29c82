"""The simulator as a ROS 2 robot: what a real robot's drivers publish, from a simulated drive.

Published (frames per REP 105; sensor QoS for the LiDARs, as drivers publish them):

| topic | type | QoS |
|---|---|---|
| `/clock` | `rosgraph_msgs/Clock` | best effort, keep last 1 |
| `/tf` | `tf2_msgs/TFMessage`: `odom` -> `base_link` at every step | reliable, keep last 100 |
| `/tf_static` | `base_link` -> `lidar` (3D) and `base_scan` (2D), the sensors' mounts | reliable, transient local |
| `/points` | `sensor_msgs/PointCloud2` in `lidar`, organized, NaN for no return | best effort, keep last 5 |
| `/scan` | `sensor_msgs/LaserScan` in `base_scan`, +inf for no return | best effort, keep last 5 |
| `/odom` | `nav_msgs/Odometry`, `odom` -> `base_link` | reliable, keep last 10 |
| `/ground_truth` | `nav_msgs/Odometry`, `map` -> `base_link`: the truth, as `record` writes it | reliable |
| `/events` | `std_msgs/String` `kidnap` when the robot was kidnapped | reliable |

Subscribed: `/cmd_vel` (`geometry_msgs/Twist`; held for 0.5 s, then the robot stops, as a base driver's
watchdog does) when no scenario is driven, and `/sim/kidnap` (`geometry_msgs/PoseStamped` in `map`: the pose
to carry the robot to, odometry untouched).

The drive runs at ``speed`` times real time (1: real time), the sim clock on ``/clock``.
"""

from __future__ import annotations

import time
from typing import Any

import gymnasium as gym
import numpy as np

from pimm_env.bags.messages import KIDNAP, laser_scan, odometry, point_cloud
from pimm_env.ros2 import domain as qos
from pimm_env.ros2.domain import Domain
from pimm_env.ros2.frames import clock, tf_message, transform
from pimm_env.ros2.graph import GraphEntry
from pimm_env.ros2.messages import ros_types

#: a base driver's watchdog: a /cmd_vel older than this stops the robot (s)
CMD_VEL_TIMEOUT = 0.5
FRAMES = {"map": "map", "odom": "odom", "base": "base_link", "lidar": "lidar", "scan": "base_scan"}


class RobotPublisher(gym.Wrapper):
    """Publishes every observation of the env on ``domain`` as a robot's drivers would, paced at ``speed`` times
    real time; between steps it takes kidnaps asked for on ``/sim/kidnap``."""

    def __init__(self, env: gym.Env, domain: Domain, speed: float = 1.0, name: str = "pimm_sim_robot") -> None:
        super().__init__(env)
        from pimm_env.sim.lidar import beam_angles_2d

        if not speed > 0:
            raise ValueError(f"speed must be > 0 (times real time), got {speed}")
        self.domain, self.speed = domain, speed
        base: Any = env.unwrapped
        self.lidar2d, self.lidar3d = base.config.lidar2d, base.config.lidar3d
        self.angles = beam_angles_2d(self.lidar2d)
        types = {"/points": "sensor_msgs/msg/PointCloud2", "/scan": "sensor_msgs/msg/LaserScan",
                 "/odom": "nav_msgs/msg/Odometry", "/ground_truth": "nav_msgs/msg/Odometry",
                 "/events": "std_msgs/msg/String"}  # fmt: skip
        profiles = {"/points": qos.SENSOR, "/scan": qos.SENSOR}
        self.pubs = {topic: domain.publisher(topic, kind, profiles.get(topic, qos.DEFAULT))
                     for topic, kind in types.items()}  # fmt: skip
        self.pubs["/clock"] = domain.publisher("/clock", "rosgraph_msgs/msg/Clock", qos.CLOCK)
        self.pubs["/tf"] = domain.publisher("/tf", "tf2_msgs/msg/TFMessage", qos.TF)
        self.pubs["/tf_static"] = domain.publisher("/tf_static", "tf2_msgs/msg/TFMessage", qos.LATCHED)
        self.kidnaps = domain.subscription("/sim/kidnap", "geometry_msgs/msg/PoseStamped")
        self.cmd_vel = domain.subscription("/cmd_vel", "geometry_msgs/msg/Twist")
        self.graph = GraphEntry(domain, name)
        self.graph.announce([*self.pubs.values(), self.kidnaps, self.cmd_vel])
        self._wall0: float | None = None
        self._sim0 = 0.0
        self.steps = 0

    def _mounts(self, seconds: float) -> Any:
        l3, l2 = self.lidar3d, self.lidar2d
        lidar = transform(seconds, FRAMES["base"], FRAMES["lidar"], np.array([l3.mount_x, l3.mount_y,
                          np.radians(l3.mount_yaw_deg)]), l3.height, np.radians(l3.mount_roll_deg),
                          np.radians(l3.mount_pitch_deg))  # fmt: skip
        scan = transform(seconds, FRAMES["base"], FRAMES["scan"],
                         np.array([l2.mount_x, l2.mount_y, np.radians(l2.mount_yaw_deg)]), l2.height)  # fmt: skip
        return tf_message([lidar, scan])

    def _pace(self, sim_time: float) -> None:
        """Sleep until the wall clock has caught up with ``sim_time`` at ``speed``."""
        if self._wall0 is None:
            self._wall0, self._sim0 = time.monotonic(), sim_time
        lag = self._wall0 + (sim_time - self._sim0) / self.speed - time.monotonic()
        if lag > 0:
            time.sleep(lag)

    def _publish(self, obs: dict[str, np.ndarray], info: dict[str, Any], first: bool) -> None:
        store, t = ros_types(), float(obs["time"][0])
        self._pace(t)
        self.pubs["/clock"].publish(clock(t))
        if first:
            self.pubs["/tf_static"].publish(self._mounts(t))
        if info.get("kidnapped"):
            self.pubs["/events"].publish(store.types["std_msgs/msg/String"](data=KIDNAP))
        if (info.get("fresh_cloud") or first) and self.lidar3d.enabled:
            cloud_t = float(obs["cloud_time"][0])
            msg = point_cloud(store, cloud_t, obs["cloud"], obs["cloud_mask"], self.lidar3d.layers)
            self.pubs["/points"].publish(msg)
        if (info.get("fresh_scan") or first) and self.lidar2d.enabled:
            scan_t = float(obs["scan_time"][0])
            self.pubs["/scan"].publish(laser_scan(store, scan_t, obs["scan"], self.angles, self.lidar2d))
        self.pubs["/ground_truth"].publish(odometry(store, t, info["true_pose"], FRAMES["map"]))
        self.pubs["/odom"].publish(odometry(store, t, obs["odom"], FRAMES["odom"]))
        self.pubs["/tf"].publish(tf_message([transform(t, FRAMES["odom"], FRAMES["base"], obs["odom"])]))
        self.steps += 1

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        obs, info = self.env.reset(seed=seed, options=options)
        kidnap = (options or {}).get("kidnap")
        kidnapped = kidnap is not None and kidnap is not False
        self._publish(obs, {**info, "kidnapped": kidnapped}, first=not kidnapped)
        return obs, info

    def step(self, action):
        asked = self.kidnaps.take()
        if asked:  # carried away between two steps: the drive goes on from the new pose
            obs, info = self.reset(options={"kidnap": planar_pose_of(asked[-1][1])})
            return obs, 0.0, False, False, {**info, "kidnapped": True, "collision": False}
        obs, reward, terminated, truncated, info = self.env.step(action)
        self._publish(obs, info, first=False)
        return obs, reward, terminated, truncated, info


def planar_pose_of(msg: Any) -> list[float]:
    from pimm_env.bags.messages import planar_pose

    return [float(v) for v in planar_pose(msg, "/sim/kidnap")]


def follow_cmd_vel(robot: RobotPublisher, seconds: float | None) -> int:
    """Drive by ``/cmd_vel`` (the newest command, zero once it is older than ``CMD_VEL_TIMEOUT``) for ``seconds`` of
    sim time (None: until interrupted); returns the steps taken."""
    command, heard = np.zeros(2, dtype=np.float32), -np.inf
    base: Any = robot.unwrapped
    start = float(base.sim_time)
    while seconds is None or float(base.sim_time) - start < seconds:
        taken = robot.cmd_vel.take()
        if taken:
            twist = taken[-1][1]
            command, heard = np.array([twist.linear.x, twist.angular.z], dtype=np.float32), time.monotonic()
        if time.monotonic() - heard > CMD_VEL_TIMEOUT:
            command = np.zeros(2, dtype=np.float32)
        space: Any = robot.action_space
        robot.step(np.clip(command, space.low, space.high))
    return robot.steps


def run_sim_robot(
    world: str = "iilab",
    scenario: str | None = None,
    seed: int = 0,
    sensors: str = "thesis",
    speed: float = 1.0,
    seconds: float | None = None,
    discovery: str = "localhost",
    on_ready: Any = None,
    domain: int | None = None,
) -> dict[str, Any]:
    """Publish a simulated robot in ``world``: drive ``scenario`` (its waypoints, and its kidnap if it has one)
    or, without one, follow ``/cmd_vel`` for ``seconds`` of sim time, in the ROS 2 ``domain`` (None:
    ``ROS_DOMAIN_ID``). Returns what was done."""
    from pimm_env.driving.rollout import run
    from pimm_env.driving.scenarios import get_scenario
    from pimm_env.envs.iilab_env import IILabEnv
    from pimm_env.world.files import load_world

    loaded = load_world(world)
    chosen = get_scenario(scenario, loaded) if scenario else None
    env = IILabEnv(world=loaded, terminate_on_collision=False, sensors=sensors)
    with Domain(discovery, domain) as dds:
        robot = RobotPublisher(env, dds, speed)
        done: dict[str, Any] = {"scenario": scenario, "interrupted": False}
        try:
            if on_ready is not None:
                on_ready(robot)
            if chosen is not None:
                result = run(chosen, seed=seed, env=robot)
                done.update(completed=result.completed, collided=result.collided)
            else:
                robot.reset(seed=seed)
                follow_cmd_vel(robot, seconds)
        except KeyboardInterrupt:
            done["interrupted"] = True
        finally:
            robot.close()
        return {**done, "steps": robot.steps, "sim_seconds": round(float(env.sim_time), 3)}
