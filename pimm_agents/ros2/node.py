"""A localizer as a ROS 2 node with nav2 AMCL's interface, over Cyclone DDS.

Subscribed: the 3D cloud (``points_topic``, any PointCloud2 layout: placed into the LiDAR layout's grid by its
points' angles), the 2D scan (``scan_topic``), odometry from ``/tf`` (``odom`` -> ``base_link``; or
``nav_msgs/Odometry`` on ``odom_topic``), the LiDAR's mount from ``/tf_static`` (``base_link`` -> the cloud's
frame), ``/initialpose``, and ``/clock`` with ``use_sim_time``.

Published after every update: the pose on ``amcl_pose`` (reliable, transient local, depth 1, as nav2) with the
*published* covariance (``published_covariance``: it covers every live hypothesis while the status is not
``localized``), TF ``map`` -> ``odom`` future-dated by ``transform_tolerance``, ``particle_cloud``
(``nav2_msgs/ParticleCloud``, best effort), the hypotheses as a ``geometry_msgs/PoseArray`` on
``hypotheses``, and the status on ``/diagnostics`` (``diagnostic_msgs/DiagnosticArray``: ``lost`` /
``ambiguous`` / ``localized``, what the guard set aside, the clouds skipped, the update's time). With
``publish_map``: the world's occupancy grid on ``/map`` (transient local). nav2 AMCL's services,
``reinitialize_global_localization`` and ``set_initial_pose``, as ``rmw_cyclonedds_cpp`` carries them.

Real time: each spin takes everything that arrived; when several clouds (or scans) wait, the newest is used and
the others are counted as skipped, never dropped silently. Every odometry message closes a step, as in a
replay; when several wait, the newest closes it (odometry is a pose, not an increment: nothing is lost).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

import numpy as np

from pimm_agents.localizer import PoseEstimate, published_covariance
from pimm_agents.ros2.node_config import NodeConfig
from pimm_env.errors import PimmError
from pimm_env.geometry import compose, relative_motion
from pimm_env.ros2 import domain as qos
from pimm_env.ros2.domain import Domain
from pimm_env.ros2.frames import header, mount, planar, quaternion, seconds_of, tf_message, transform
from pimm_env.ros2.graph import GraphEntry
from pimm_env.ros2.messages import ros_types
from pimm_env.ros2.services import ServiceServer

#: diagnostic_msgs/DiagnosticStatus levels by status
LEVELS = {"localized": 0, "ambiguous": 1, "lost": 2}  # OK, WARN, ERROR
#: makes a localizer for the LiDAR mount read from /tf_static (``Lidar3DConfig`` fields; None: the preset's)
LocalizerMaker = Callable[[dict[str, float] | None], Any]


def pose_message(x: float, y: float, yaw: float) -> Any:
    t = ros_types().types
    return t["geometry_msgs/msg/Pose"](
        position=t["geometry_msgs/msg/Point"](x=float(x), y=float(y), z=0.0),
        orientation=quaternion(0.0, 0.0, float(yaw)),
    )


def covariance_6x6(cov3: np.ndarray) -> np.ndarray:
    """A planar (x, y, yaw) covariance as ROS's row-major 6 x 6 (x, y, z, roll, pitch, yaw)."""
    out = np.zeros((6, 6))
    index = [0, 1, 5]
    out[np.ix_(index, index)] = np.asarray(cov3, dtype=float)
    return out.reshape(-1)


def covariance_3x3(cov36: Any) -> np.ndarray:
    full = np.asarray(cov36, dtype=float).reshape(6, 6)
    index = [0, 1, 5]
    return full[np.ix_(index, index)]


class LocalizationNode:
    """Feeds a localizer from ROS 2 topics and publishes what nav2 reads. ``spin_once`` handles what arrived
    and returns the newest estimate (None when no odometry closed a step); ``close`` ends the node's endpoints
    (the ``Domain`` is the caller's)."""

    def __init__(
        self,
        make: LocalizerMaker,
        lidar3d: Any,
        lidar2d: Any,
        domain: Domain,
        config: NodeConfig,
        name: str = "pimm_localization",
        occupancy: Any = None,
    ) -> None:
        self.make, self.lidar3d, self.lidar2d, self.config = make, lidar3d, lidar2d, config
        self.domain, self.occupancy = domain, occupancy
        c = config
        self.subs = {
            "tf": domain.subscription("/tf", "tf2_msgs/msg/TFMessage", qos.TF),
            "tf_static": domain.subscription("/tf_static", "tf2_msgs/msg/TFMessage", qos.LATCHED),
            "points": domain.subscription(c.points_topic, "sensor_msgs/msg/PointCloud2", qos.SENSOR),
            "scan": domain.subscription(c.scan_topic, "sensor_msgs/msg/LaserScan", qos.SENSOR),
            "initialpose": domain.subscription("/initialpose", "geometry_msgs/msg/PoseWithCovarianceStamped"),
        }
        if c.odom_source == "topic":
            self.subs["odom"] = domain.subscription(c.odom_topic, "nav_msgs/msg/Odometry")
        if c.use_sim_time:
            self.subs["clock"] = domain.subscription("/clock", "rosgraph_msgs/msg/Clock", qos.CLOCK)
        self.pubs = {
            "pose": domain.publisher(c.pose_topic, "geometry_msgs/msg/PoseWithCovarianceStamped", qos.LATCHED),
            "tf": domain.publisher("/tf", "tf2_msgs/msg/TFMessage", qos.TF),
            "particles": domain.publisher("particle_cloud", "nav2_msgs/msg/ParticleCloud", qos.SENSOR),
            "hypotheses": domain.publisher("hypotheses", "geometry_msgs/msg/PoseArray"),
            "diagnostics": domain.publisher("/diagnostics", "diagnostic_msgs/msg/DiagnosticArray"),
        }
        if c.publish_map and occupancy is not None:
            self.pubs["map"] = domain.publisher("/map", "nav_msgs/msg/OccupancyGrid", qos.LATCHED)
        self.services = [  # nav2 AMCL's, as rmw_cyclonedds_cpp carries services (pimm_env/ros2/services.py)
            ServiceServer(domain, "reinitialize_global_localization", "std_srvs/srv/Empty", self._reinitialize),
            ServiceServer(
                domain, "set_initial_pose", "nav2_msgs/srv/SetInitialPose", lambda r: self._set_initial_pose(r.pose)
            ),
        ]
        self.graph = GraphEntry(domain, name)
        self.graph.announce([*self.subs.values(), *self.pubs.values()], tuple(self.services))
        self.name = name
        self.localizer: Any = None
        self.mount: dict[str, float] | None = None
        self.mount_source = "preset"
        self.counts = {
            "updates": 0,
            "skipped_clouds": 0,
            "skipped_scans": 0,
            "skipped_odometry": 0,
            "unusable_clouds": 0,
            "unusable_scans": 0,
            "non_finite_odometry": 0,
        }
        self.latencies_ms: list[float] = []  # a used cloud's arrival to its pose's publication, after the first
        self.first_update_ms: float | None = None
        self.update_ms: list[float] = []
        self.problems: list[str] = []  # the newest few, said in the status
        self._epoch: float | None = None  # the first stamp seen: observation times count from it
        self._cloud: tuple[float, float, Any] | None = None  # (arrival, stamp, message) not yet used
        self._scan: tuple[float, float, Any] | None = None
        self._grid = (np.zeros((lidar3d.num_points, 3), np.float32), np.zeros(lidar3d.num_points, np.int8), 0.0)
        self._ranges = (np.full(lidar2d.beams, lidar2d.max_range, np.float32), 0.0)
        self._first_sensor_at: float | None = None  # when the first cloud or scan arrived
        self._cloud_frame: str | None = None
        self._cloud_arrival: float | None = None
        self._static: dict[str, dict[str, float]] = {}  # the mounts on /tf_static, by child frame
        self._reset_to: tuple[np.ndarray, np.ndarray | None] | str | None = None  # "global": forget the pose
        self.sim_time: float | None = None
        self.estimate: PoseEstimate | None = None
        if "map" in self.pubs:
            self.pubs["map"].publish(self._map_message())

    # -- inputs -------------------------------------------------------------------------------------------
    def _rel(self, stamp: float) -> float:
        if self._epoch is None:
            self._epoch = stamp
        return stamp - self._epoch

    def _note(self, problem: str) -> None:
        self.problems = [*self.problems[-4:], problem]

    def _take_inputs(self) -> tuple[float, float, np.ndarray] | None:
        """Everything waiting; returns the newest odometry (arrival, stamp, pose) or None."""
        c = self.config
        for _, msg in self.subs["tf_static"].take():  # the base's sensors, by frame
            for tr in msg.transforms:
                if tr.header.frame_id == c.base_frame_id:
                    self._static[tr.child_frame_id] = mount(tr)
        if "clock" in self.subs:
            for _, msg in self.subs["clock"].take():
                self.sim_time = seconds_of(msg.clock)
        for server in self.services:
            server.spin_once()
        for _, msg in self.subs["initialpose"].take():
            self._set_initial_pose(msg)
        for kind in ("points", "scan"):
            taken = self.subs[kind].take()
            if not taken:
                continue
            waiting = self._cloud if kind == "points" else self._scan
            self.counts["skipped_clouds" if kind == "points" else "skipped_scans"] += (
                len(taken) - 1 + (waiting is not None)
            )
            arrival, msg = taken[-1]
            newest = (arrival, seconds_of(msg.header.stamp), msg)
            if kind == "points":
                self._cloud = newest
                self._cloud_frame = msg.header.frame_id
            else:
                self._scan = newest
            if self._first_sensor_at is None:
                self._first_sensor_at = arrival
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
            self._note("an odometry message with non-finite values was set aside")
            return None
        return newest

    def _set_initial_pose(self, msg: Any) -> dict[str, Any]:
        """A ``PoseWithCovarianceStamped`` on ``/initialpose`` or in ``set_initial_pose``: restart the localizer
        there at its next update."""
        pose = np.array([msg.pose.pose.position.x, msg.pose.pose.position.y, planar_yaw(msg.pose.pose)])
        cov = covariance_3x3(msg.pose.covariance)
        if np.all(np.isfinite(pose)) and np.all(np.isfinite(cov)):
            self._reset_to = (pose, cov)
        else:
            self._note("an initial pose with non-finite values was set aside")
        return {}

    def _reinitialize(self, request: Any) -> dict[str, Any]:
        """``reinitialize_global_localization``: forget the pose, a global start at the next update."""
        self._reset_to = "global"
        return {}

    def _ready(self, now: float) -> bool:
        """Build the localizer once a sensor spoke and the LiDAR's mount is known, or ``mount_wait`` has passed
        (a robot without a 3D LiDAR, or one whose mount is not on /tf_static: the sensors preset's mount)."""
        if self.localizer is not None:
            return True
        if self._first_sensor_at is None:
            return False
        frame = self._cloud_frame
        self.mount = self._static.get(frame) if frame is not None else None
        if self.mount is None and now - self._first_sensor_at < self.config.mount_wait:
            return False
        if self.mount is not None:
            self.mount_source = f"/tf_static {self.config.base_frame_id} -> {frame}"
        elif self.lidar3d.enabled:
            self._note(f"no {self.config.base_frame_id} -> {frame} on /tf_static: the sensors preset's mount is used")
        self.localizer = self.make(self.mount)
        self._reset()
        return True

    def _reset(self, to: tuple[np.ndarray, np.ndarray | None] | None = None) -> None:
        c = self.config
        if to is None and c.set_initial_pose:
            p = c.initial_pose
            to = (np.array([p.get("x", 0.0), p.get("y", 0.0), p.get("yaw", 0.0)], dtype=float), None)
        if to is None:
            self.localizer.reset(seed=c.seed)
        else:
            self.localizer.reset(seed=c.seed, initial_pose=to[0], initial_cov=to[1])

    def _observation(self, stamp: float) -> dict[str, np.ndarray]:
        from pimm_env.bags.layout import organize
        from pimm_env.bags.messages import cloud_points, scan_ranges

        if self._cloud is not None:
            arrival, cloud_stamp, msg = self._cloud
            where = f"{self.config.points_topic} message {self.subs['points'].received - 1}"
            try:
                cloud, mask = organize(cloud_points(msg, where), self.lidar3d, where)
                self._grid = (cloud, mask, self._rel(cloud_stamp))
                self._cloud_arrival = arrival
            except PimmError as error:
                self.counts["unusable_clouds"] += 1
                self._note(str(error))
            self._cloud = None
        if self._scan is not None:
            _, scan_stamp, msg = self._scan
            where = f"{self.config.scan_topic} message {self.subs['scan'].received - 1}"
            try:
                self._ranges = (
                    scan_ranges(msg, self.lidar2d.beams, self.lidar2d.max_range, where),
                    self._rel(scan_stamp),
                )
            except PimmError as error:
                self.counts["unusable_scans"] += 1
                self._note(str(error))
            self._scan = None
        cloud, mask, cloud_time = self._grid
        ranges, scan_time = self._ranges
        return {
            "odom": np.zeros(3, np.float32),
            "cloud": cloud,
            "cloud_mask": mask,
            "scan": ranges,
            "time": np.array([self._rel(stamp)]),
            "cloud_time": np.array([cloud_time]),
            "scan_time": np.array([scan_time]),
        }

    # -- one spin ---------------------------------------------------------------------------------------------
    def spin_once(self) -> PoseEstimate | None:
        odometry = self._take_inputs()
        now = time.monotonic()
        if odometry is None or not self._ready(now):
            return None
        if self._reset_to == "global":
            self.localizer.reset(seed=self.config.seed)
        elif isinstance(self._reset_to, tuple):
            self._reset(self._reset_to)
        self._reset_to = None
        _, stamp, odom = odometry
        obs = self._observation(stamp)
        obs["odom"] = odom.astype(np.float32)
        fresh_cloud = self._cloud_arrival
        self._cloud_arrival = None
        start = time.perf_counter()
        estimate = self.localizer.update(obs)
        spent = (time.perf_counter() - start) * 1e3
        self.counts["updates"] += 1
        self._publish(estimate, stamp, odom)
        if self.estimate is None:  # the first update loads what the localizer loads lazily: said apart
            self.first_update_ms = spent
        else:
            self.update_ms.append(spent)
            if fresh_cloud is not None:
                self.latencies_ms.append((time.monotonic() - fresh_cloud) * 1e3)
        self.estimate = estimate
        return estimate

    def spin(
        self, seconds: float | None = None, should_stop: Callable[[], bool] | None = None, period: float = 0.002
    ) -> None:
        """Spin until ``seconds`` of wall time passed or ``should_stop()`` says so (None: until interrupted)."""
        end = None if seconds is None else time.monotonic() + seconds
        while (end is None or time.monotonic() < end) and not (should_stop and should_stop()):
            if self.spin_once() is None:
                time.sleep(period)

    # -- outputs ----------------------------------------------------------------------------------------------
    def _publish(self, estimate: PoseEstimate, stamp: float, odom: np.ndarray) -> None:
        t, c = ros_types().types, self.config
        pose = pose_message(estimate.x, estimate.y, estimate.theta)
        cov = published_covariance(estimate)
        self.pubs["pose"].publish(
            t["geometry_msgs/msg/PoseWithCovarianceStamped"](
                header=header(stamp, c.global_frame_id),
                pose=t["geometry_msgs/msg/PoseWithCovariance"](pose=pose, covariance=covariance_6x6(cov)),
            )
        )
        if c.tf_broadcast:  # map -> odom = (map -> base) o (odom -> base)^-1, future-dated as nav2 does
            odom_in_base = relative_motion(np.asarray(odom, dtype=float), np.zeros(3))
            map_odom = compose(estimate.pose, odom_in_base)[0]
            self.pubs["tf"].publish(
                tf_message([transform(stamp + c.transform_tolerance, c.global_frame_id, c.odom_frame_id, map_odom)])
            )
        particles = estimate.inside.get("particles")
        if particles is not None and len(particles):
            weight = 1.0 / len(particles)
            self.pubs["particles"].publish(
                t["nav2_msgs/msg/ParticleCloud"](
                    header=header(stamp, c.global_frame_id),
                    particles=[
                        t["nav2_msgs/msg/Particle"](pose=pose_message(*p[:3]), weight=weight) for p in particles
                    ],
                )
            )
        hypotheses = estimate.hypotheses or ()
        self.pubs["hypotheses"].publish(
            t["geometry_msgs/msg/PoseArray"](
                header=header(stamp, c.global_frame_id), poses=[pose_message(h.x, h.y, h.theta) for h in hypotheses]
            )
        )
        self.pubs["diagnostics"].publish(self._diagnostics(estimate, stamp))

    def _diagnostics(self, estimate: PoseEstimate, stamp: float) -> Any:
        t = ros_types().types
        values = {
            "status": estimate.status,
            "hypotheses": len(estimate.hypotheses),
            "x": f"{estimate.x:.3f}",
            "y": f"{estimate.y:.3f}",
            "yaw": f"{estimate.theta:.4f}",
            "update_ms": f"{self.update_ms[-1]:.1f}" if self.update_ms else "",
            "mount": self.mount_source,
            **{k: v for k, v in self.counts.items()},
            **{f"set_aside.{k}": v for k, v in estimate.set_aside.items()},
        }
        if self.problems:
            values["last_problem"] = self.problems[-1]
        status = t["diagnostic_msgs/msg/DiagnosticStatus"](
            level=LEVELS[estimate.status],
            name=f"{self.name}: localization",
            message=estimate.status,
            hardware_id=self.name,
            values=[t["diagnostic_msgs/msg/KeyValue"](key=k, value=str(v)) for k, v in values.items()],
        )
        return t["diagnostic_msgs/msg/DiagnosticArray"](header=header(self.now(), ""), status=[status])

    def now(self) -> float:
        """The node's clock, as ROS 2's ``now()``: ``/clock`` with ``use_sim_time`` (once heard), else the wall
        clock. Poses and transforms are stamped with the sensors' stamps instead, as nav2 AMCL stamps them."""
        if self.config.use_sim_time:
            return self.sim_time if self.sim_time is not None else 0.0
        return time.time()

    def _map_message(self) -> Any:
        t, grid = ros_types().types, self.occupancy.grid
        data = np.full(grid.shape, -1, dtype=np.int8)
        data[self.occupancy.free] = 0
        data[self.occupancy.occupied] = 100
        origin = pose_message(grid.origin[0], grid.origin[1], 0.0)
        info = t["nav_msgs/msg/MapMetaData"](
            map_load_time=header(0.0, "").stamp,
            resolution=float(grid.resolution),
            width=int(grid.shape[1]),
            height=int(grid.shape[0]),
            origin=origin,
        )
        return t["nav_msgs/msg/OccupancyGrid"](
            header=header(0.0, self.config.global_frame_id), info=info, data=data.reshape(-1)
        )

    def report(self) -> dict[str, Any]:
        """What the node did: counts, update times and cloud-to-pose latencies (median, p99, max, ms; the first
        update, which loads what the localizer loads lazily, apart)."""

        def spread(values: list[float]) -> dict[str, float] | None:
            if not values:
                return None
            a = np.asarray(values)
            return {
                "median": round(float(np.median(a)), 2),
                "p99": round(float(np.percentile(a, 99)), 2),
                "max": round(float(a.max()), 2),
            }

        first = None if self.first_update_ms is None else round(self.first_update_ms, 1)
        return {
            **self.counts,
            "first_update_ms": first,
            "update_ms": spread(self.update_ms),
            "latency_ms": spread(self.latencies_ms),
            "mount": self.mount_source,
            "status": None if self.estimate is None else self.estimate.status,
        }

    def close(self) -> None:
        self.subs.clear()
        self.pubs.clear()


def planar_yaw(pose: Any) -> float:
    q = pose.orientation
    return float(np.arctan2(2 * (q.w * q.z + q.x * q.y), 1 - 2 * (q.y**2 + q.z**2)))
