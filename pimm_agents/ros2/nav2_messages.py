"""What the localization node publishes, as nav2's messages: the pose with its published covariance, TF
``map`` -> ``odom``, the particle cloud, the hypotheses, the status as diagnostics and the occupancy grid."""

from __future__ import annotations

from typing import Any

import numpy as np

from pimm_agents.localizer import PoseEstimate, published_covariance
from pimm_env.geometry import compose, relative_motion
from pimm_env.ros2.frames import header, quaternion, tf_message, transform
from pimm_env.ros2.messages import ros_types

#: diagnostic_msgs/DiagnosticStatus levels by status
LEVELS = {"localized": 0, "ambiguous": 1, "lost": 2}  # OK, WARN, ERROR


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


def pose_with_covariance(estimate: PoseEstimate, stamp: float, frame: str) -> Any:
    """``amcl_pose``: the estimate with the covariance a consumer without the status should see."""
    t = ros_types().types
    pose = pose_message(estimate.x, estimate.y, estimate.theta)
    covariance = covariance_6x6(published_covariance(estimate))
    return t["geometry_msgs/msg/PoseWithCovarianceStamped"](
        header=header(stamp, frame), pose=t["geometry_msgs/msg/PoseWithCovariance"](pose=pose, covariance=covariance)
    )


def map_to_odom(estimate: PoseEstimate, odom: np.ndarray, stamp: float, config: Any) -> Any:
    """TF ``map`` -> ``odom`` (REP 105): (map -> base) o (odom -> base)^-1, stamped ``stamp``."""
    odom_in_base = relative_motion(np.asarray(odom, dtype=float), np.zeros(3))
    map_odom = compose(estimate.pose, odom_in_base)[0]
    return tf_message([transform(stamp, config.global_frame_id, config.odom_frame_id, map_odom)])


def particle_cloud(estimate: PoseEstimate, stamp: float, frame: str) -> Any:
    """``nav2_msgs/ParticleCloud`` of the particles the estimate shows (equal weights: they were resampled)."""
    t = ros_types().types
    particles = estimate.inside["particles"]
    weight = 1.0 / len(particles)
    cloud = [t["nav2_msgs/msg/Particle"](pose=pose_message(*p[:3]), weight=weight) for p in particles]
    return t["nav2_msgs/msg/ParticleCloud"](header=header(stamp, frame), particles=cloud)


def hypotheses_array(estimate: PoseEstimate, stamp: float, frame: str) -> Any:
    poses = [pose_message(h.x, h.y, h.theta) for h in estimate.hypotheses]
    return ros_types().types["geometry_msgs/msg/PoseArray"](header=header(stamp, frame), poses=poses)


def diagnostics(estimate: PoseEstimate, name: str, now: float, values: dict[str, Any]) -> Any:
    """The status as ``diagnostic_msgs/DiagnosticArray`` (``localized`` OK, ``ambiguous`` WARN, ``lost``
    ERROR) with the pose, what the guard set aside and the node's own ``values``."""
    t = ros_types().types
    shown = {
        "status": estimate.status,
        "hypotheses": len(estimate.hypotheses),
        "x": f"{estimate.x:.3f}",
        "y": f"{estimate.y:.3f}",
        "yaw": f"{estimate.theta:.4f}",
        **values,
        **{f"set_aside.{k}": v for k, v in estimate.set_aside.items()},
    }
    status = t["diagnostic_msgs/msg/DiagnosticStatus"](
        level=LEVELS[estimate.status],
        name=f"{name}: localization",
        message=estimate.status,
        hardware_id=name,
        values=[t["diagnostic_msgs/msg/KeyValue"](key=k, value=str(v)) for k, v in shown.items()],
    )
    return t["diagnostic_msgs/msg/DiagnosticArray"](header=header(now, ""), status=[status])


def occupancy_grid(occupancy: Any, frame: str) -> Any:
    """The world's occupancy grid as ``nav_msgs/OccupancyGrid`` (free 0, occupied 100, unknown -1)."""
    t, grid = ros_types().types, occupancy.grid
    data = np.full(grid.shape, -1, dtype=np.int8)
    data[occupancy.free] = 0
    data[occupancy.occupied] = 100
    info = t["nav_msgs/msg/MapMetaData"](
        map_load_time=header(0.0, "").stamp,
        resolution=float(grid.resolution),
        width=int(grid.shape[1]),
        height=int(grid.shape[0]),
        origin=pose_message(grid.origin[0], grid.origin[1], 0.0),
    )
    return t["nav_msgs/msg/OccupancyGrid"](header=header(0.0, frame), info=info, data=data.reshape(-1))
