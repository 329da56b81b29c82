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

from pimm_agents.localizer import PoseEstimate
from pimm_agents.ros2.nav2_messages import (
    covariance_3x3,
    diagnostics,
    hypotheses_array,
    map_to_odom,
    occupancy_grid,
    particle_cloud,
    pose_with_covariance,
)
from pimm_agents.ros2.node_config import NodeConfig
from pimm_agents.ros2.robot_inputs import RobotInputs
from pimm_env.bags.messages import planar_pose
from pimm_env.ros2 import domain as qos
from pimm_env.ros2.domain import Domain, Publisher, Subscription
from pimm_env.ros2.graph import GraphEntry
from pimm_env.ros2.services import ServiceServer

#: makes a localizer for the LiDAR mount read from /tf_static (``Lidar3DConfig`` fields; None: the preset's)
LocalizerMaker = Callable[[dict[str, float] | None], Any]


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
        self.make, self.lidar3d, self.config, self.domain = make, lidar3d, config, domain
        c = config
        self.inputs = RobotInputs(domain, config, lidar3d, lidar2d)
        self.initialpose = domain.subscription("/initialpose", "geometry_msgs/msg/PoseWithCovarianceStamped")
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
        endpoints: list[Publisher | Subscription] = [*self.inputs.subs.values(), self.initialpose, *self.pubs.values()]
        self.graph.announce(endpoints, tuple(self.services))
        self.name = name
        self.localizer: Any = None
        self.mount: dict[str, float] | None = None
        self.mount_source = "preset"
        self.updates = 0
        self.latencies_ms: list[float] = []  # a used cloud's arrival to its pose's publication, after the first
        self.first_update_ms: float | None = None
        self.update_ms: list[float] = []
        self._reset_to: tuple[np.ndarray, np.ndarray | None] | str | None = None  # "global": forget the pose
        self.estimate: PoseEstimate | None = None
        if "map" in self.pubs:
            self.pubs["map"].publish(occupancy_grid(occupancy, config.global_frame_id))

    # -- control ----------------------------------------------------------------------------------------------
    def _set_initial_pose(self, msg: Any) -> dict[str, Any]:
        """A ``PoseWithCovarianceStamped`` on ``/initialpose`` or in ``set_initial_pose``: restart the localizer
        there at its next update."""
        pose = planar_pose(msg, "initial pose")
        cov = covariance_3x3(msg.pose.covariance)
        if np.all(np.isfinite(pose)) and np.all(np.isfinite(cov)):
            self._reset_to = (pose, cov)
        else:
            self.inputs.note("an initial pose with non-finite values was set aside")
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
        inputs, base = self.inputs, self.config.base_frame_id
        if inputs.first_sensor_at is None:
            return False
        self.mount = inputs.lidar_mount()
        if self.mount is None and now - inputs.first_sensor_at < self.config.mount_wait:
            return False
        if self.mount is not None:
            self.mount_source = f"/tf_static {base} -> {inputs.cloud_frame}"
        elif self.lidar3d.enabled:
            inputs.note(f"no {base} -> {inputs.cloud_frame} on /tf_static: the sensors preset's mount is used")
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

    # -- one spin ---------------------------------------------------------------------------------------------
    def spin_once(self) -> PoseEstimate | None:
        for server in self.services:
            server.spin_once()
        for _, msg in self.initialpose.take():
            self._set_initial_pose(msg)
        odometry = self.inputs.take()
        now = time.monotonic()
        if odometry is None or not self._ready(now):
            return None
        if self._reset_to == "global":
            self.localizer.reset(seed=self.config.seed)
        elif isinstance(self._reset_to, tuple):
            self._reset(self._reset_to)
        self._reset_to = None
        _, stamp, odom = odometry
        obs, fresh_cloud = self.inputs.observation(stamp, odom)
        start = time.perf_counter()
        estimate = self.localizer.update(obs)
        spent = (time.perf_counter() - start) * 1e3
        self.updates += 1
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
        c = self.config
        self.pubs["pose"].publish(pose_with_covariance(estimate, stamp, c.global_frame_id))
        if c.tf_broadcast:  # future-dated, as nav2 AMCL does
            self.pubs["tf"].publish(map_to_odom(estimate, odom, stamp + c.transform_tolerance, c))
        if len(estimate.inside.get("particles", ())):
            self.pubs["particles"].publish(particle_cloud(estimate, stamp, c.global_frame_id))
        self.pubs["hypotheses"].publish(hypotheses_array(estimate, stamp, c.global_frame_id))
        values = {
            "update_ms": f"{self.update_ms[-1]:.1f}" if self.update_ms else "",
            "mount": self.mount_source,
            "updates": self.updates,
            **self.inputs.counts,
            **({"last_problem": self.inputs.problems[-1]} if self.inputs.problems else {}),
        }
        self.pubs["diagnostics"].publish(diagnostics(estimate, self.name, self.now(), values))

    def now(self) -> float:
        """The node's clock, as ROS 2's ``now()``: ``/clock`` with ``use_sim_time`` (once heard), else the wall
        clock. Poses and transforms are stamped with the sensors' stamps instead, as nav2 AMCL stamps them."""
        if self.config.use_sim_time:
            return self.inputs.sim_time if self.inputs.sim_time is not None else 0.0
        return time.time()

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
            "updates": self.updates,
            **self.inputs.counts,
            "first_update_ms": first,
            "update_ms": spread(self.update_ms),
            "latency_ms": spread(self.latencies_ms),
            "mount": self.mount_source,
            "status": None if self.estimate is None else self.estimate.status,
        }

    def close(self) -> None:
        """Let go of the endpoints (the ``Domain``, the caller's, deletes them with its participant)."""
        self.inputs.subs.clear()
        self.pubs.clear()
