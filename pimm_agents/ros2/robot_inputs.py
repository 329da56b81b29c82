"""What a robot's drivers send the localization node, taken as it arrives and made into the env's observation.

The 3D cloud (any PointCloud2 layout: placed into the LiDAR layout's grid by its points' angles), the 2D scan,
odometry from ``/tf`` (``odom`` -> ``base_link``) or ``nav_msgs/Odometry``, the sensors' mounts from
``/tf_static`` and ``/clock``. When several clouds (or scans) wait, the newest is kept and the others are counted
as skipped; a cloud or scan that cannot be read is counted and named; odometry with a value that is not finite is
set aside and counted. Observation times count from the first stamp seen (a robot's clock reads 1.7e9 s).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from pimm_agents.ros2.node_config import NodeConfig
from pimm_env.errors import PimmError
from pimm_env.ros2 import domain as qos
from pimm_env.ros2.domain import Domain, Subscription
from pimm_env.ros2.frames import mount, planar, seconds_of


class RobotInputs:
    """The node's sensor subscriptions and what waits on them. ``take`` takes everything that arrived and
    returns the newest odometry (arrival, stamp, pose) or None; ``observation`` makes the step it closes."""

    def __init__(self, domain: Domain, config: NodeConfig, lidar3d: Any, lidar2d: Any) -> None:
        c = self.config = config
        self.lidar3d, self.lidar2d = lidar3d, lidar2d
        self.subs: dict[str, Subscription] = {
            "tf": domain.subscription("/tf", "tf2_msgs/msg/TFMessage", qos.TF),
            "tf_static": domain.subscription("/tf_static", "tf2_msgs/msg/TFMessage", qos.LATCHED),
            "points": domain.subscription(c.points_topic, "sensor_msgs/msg/PointCloud2", qos.SENSOR),
            "scan": domain.subscription(c.scan_topic, "sensor_msgs/msg/LaserScan", qos.SENSOR),
        }
        if c.odom_source == "topic":
            self.subs["odom"] = domain.subscription(c.odom_topic, "nav_msgs/msg/Odometry")
        if c.use_sim_time:
            self.subs["clock"] = domain.subscription("/clock", "rosgraph_msgs/msg/Clock", qos.CLOCK)
        self.counts = {
            "skipped_clouds": 0,
            "skipped_scans": 0,
            "skipped_odometry": 0,
            "unusable_clouds": 0,
            "unusable_scans": 0,
            "non_finite_odometry": 0,
        }
        self.problems: list[str] = []  # the newest few, said in the status
        self.sim_time: float | None = None
        self.first_sensor_at: float | None = None  # when the first cloud or scan arrived
        self.cloud_frame: str | None = None
        self.mounts: dict[str, dict[str, float]] = {}  # the base's sensors on /tf_static, by child frame
        self._epoch: float | None = None  # the first stamp seen: observation times count from it
        self._cloud: tuple[float, float, Any] | None = None  # (arrival, stamp, message) not yet used
        self._scan: tuple[float, float, Any] | None = None
        self._grid = (np.zeros((lidar3d.num_points, 3), np.float32), np.zeros(lidar3d.num_points, np.int8), 0.0)
        self._ranges = (np.full(lidar2d.beams, lidar2d.max_range, np.float32), 0.0)

    def note(self, problem: str) -> None:
        self.problems = [*self.problems[-4:], problem]

    def _rel(self, stamp: float) -> float:
        if self._epoch is None:
            self._epoch = stamp
        return stamp - self._epoch

    def lidar_mount(self) -> dict[str, float] | None:
        """The 3D LiDAR's mount from /tf_static (``Lidar3DConfig`` fields), once both it and a cloud arrived."""
        return None if self.cloud_frame is None else self.mounts.get(self.cloud_frame)

    def take(self) -> tuple[float, float, np.ndarray] | None:
        c = self.config
        for _, msg in self.subs["tf_static"].take():
            for tr in msg.transforms:
                if tr.header.frame_id == c.base_frame_id:
                    self.mounts[tr.child_frame_id] = mount(tr)
        if "clock" in self.subs:
            for _, msg in self.subs["clock"].take():
                self.sim_time = seconds_of(msg.clock)
        for kind in ("points", "scan"):
            taken = self.subs[kind].take()
            if not taken:
                continue
            waiting = self._cloud if kind == "points" else self._scan
            skipped = len(taken) - 1 + (waiting is not None)
            self.counts["skipped_clouds" if kind == "points" else "skipped_scans"] += skipped
            arrival, msg = taken[-1]
            newest = (arrival, seconds_of(msg.header.stamp), msg)
            if kind == "points":
                self._cloud, self.cloud_frame = newest, msg.header.frame_id
            else:
                self._scan = newest
            if self.first_sensor_at is None:
                self.first_sensor_at = arrival
        return self._newest_odometry()

    def _newest_odometry(self) -> tuple[float, float, np.ndarray] | None:
        c = self.config
        odometry: list[tuple[float, float, np.ndarray]] = []
        if c.odom_source == "tf":
            for arrival, msg in self.subs["tf"].take():
                for tr in msg.transforms:
                    if tr.header.frame_id == c.odom_frame_id and tr.child_frame_id == c.base_frame_id:
                        odometry.append((arrival, seconds_of(tr.header.stamp), planar(tr)))
        else:
            from pimm_env.bags.messages import planar_pose

            for arrival, msg in self.subs["odom"].take():
                odometry.append((arrival, seconds_of(msg.header.stamp), planar_pose(msg, c.odom_topic)))
        if not odometry:
            return None
        self.counts["skipped_odometry"] += len(odometry) - 1
        newest = odometry[-1]
        if not np.all(np.isfinite(newest[2])) or not np.isfinite(newest[1]):
            self.counts["non_finite_odometry"] += 1
            self.note("an odometry message with non-finite values was set aside")
            return None
        return newest

    def observation(self, stamp: float, odom: np.ndarray) -> tuple[dict[str, np.ndarray], float | None]:
        """The env's observation at odometry ``odom`` stamped ``stamp``, with the newest cloud and scan, and the
        arrival of the cloud it uses for the first time (None: no new one)."""
        from pimm_env.bags.layout import organize
        from pimm_env.bags.messages import cloud_points, scan_ranges

        fresh = None
        if self._cloud is not None:
            arrival, cloud_stamp, msg = self._cloud
            where = f"{self.config.points_topic} message {self.subs['points'].received - 1}"
            try:
                cloud, mask = organize(cloud_points(msg, where), self.lidar3d, where)
                self._grid, fresh = (cloud, mask, self._rel(cloud_stamp)), arrival
            except PimmError as error:
                self.counts["unusable_clouds"] += 1
                self.note(str(error))
            self._cloud = None
        if self._scan is not None:
            _, scan_stamp, msg = self._scan
            where = f"{self.config.scan_topic} message {self.subs['scan'].received - 1}"
            try:
                ranges = scan_ranges(msg, self.lidar2d.beams, self.lidar2d.max_range, where)
                self._ranges = (ranges, self._rel(scan_stamp))
            except PimmError as error:
                self.counts["unusable_scans"] += 1
                self.note(str(error))
            self._scan = None
        cloud, mask, cloud_time = self._grid
        ranges, scan_time = self._ranges
        obs = {
            "odom": np.asarray(odom, dtype=np.float32),
            "cloud": cloud,
            "cloud_mask": mask,
            "scan": ranges,
            "time": np.array([self._rel(stamp)]),
            "cloud_time": np.array([cloud_time]),
            "scan_time": np.array([scan_time]),
        }
        return obs, fresh
