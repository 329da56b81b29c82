"""Planar poses as ROS 2 frames and back: ``TransformStamped`` for ``/tf``, a LiDAR's mount from ``/tf_static``,
``/clock``, and the stamps all of them carry (REP 105's ``map`` -> ``odom`` -> ``base_link``)."""

from __future__ import annotations

from typing import Any

import numpy as np

from pimm_env.bags import messages
from pimm_env.bags.messages import seconds_of
from pimm_env.ros2.messages import ros_types

__all__ = ["clock", "header", "mount", "planar", "quaternion", "seconds_of", "stamp", "tf_message", "transform"]


def stamp(seconds: float) -> Any:
    return messages.time_stamp(ros_types(), seconds)


def header(seconds: float, frame: str) -> Any:
    return messages.header(ros_types(), seconds, frame)


def quaternion(roll: float, pitch: float, yaw: float) -> Any:
    """The rotation R = Rz(yaw) Ry(pitch) Rx(roll) (rad) as ``geometry_msgs/Quaternion``."""
    cr, sr, cp, sp = np.cos(roll / 2), np.sin(roll / 2), np.cos(pitch / 2), np.sin(pitch / 2)
    cy, sy = np.cos(yaw / 2), np.sin(yaw / 2)
    return ros_types().types["geometry_msgs/msg/Quaternion"](
        x=float(sr * cp * cy - cr * sp * sy),
        y=float(cr * sp * cy + sr * cp * sy),
        z=float(cr * cp * sy - sr * sp * cy),
        w=float(cr * cp * cy + sr * sp * sy),
    )


def roll_pitch_yaw(q: Any) -> tuple[float, float, float]:
    """(roll, pitch, yaw) in rad of a quaternion, the inverse of ``quaternion``."""
    roll = np.arctan2(2 * (q.w * q.x + q.y * q.z), 1 - 2 * (q.x**2 + q.y**2))
    pitch = np.arcsin(np.clip(2 * (q.w * q.y - q.z * q.x), -1.0, 1.0))
    yaw = np.arctan2(2 * (q.w * q.z + q.x * q.y), 1 - 2 * (q.y**2 + q.z**2))
    return float(roll), float(pitch), float(yaw)


def transform(seconds: float, parent: str, child: str, pose: np.ndarray, z: float = 0.0,
              roll: float = 0.0, pitch: float = 0.0) -> Any:  # fmt: skip
    """``geometry_msgs/TransformStamped`` of ``child`` in ``parent`` at a planar ``pose`` (x, y, yaw)."""
    t = ros_types().types
    x, y, yaw = (float(v) for v in pose)
    return t["geometry_msgs/msg/TransformStamped"](
        header=header(seconds, parent),
        child_frame_id=child,
        transform=t["geometry_msgs/msg/Transform"](
            translation=t["geometry_msgs/msg/Vector3"](x=x, y=y, z=float(z)),
            rotation=quaternion(roll, pitch, yaw),
        ),
    )


def tf_message(transforms: list[Any]) -> Any:
    return ros_types().types["tf2_msgs/msg/TFMessage"](transforms=transforms)


def planar(transform_stamped: Any) -> np.ndarray:
    """(x, y, yaw) of a ``TransformStamped``."""
    tr = transform_stamped.transform
    return np.array([tr.translation.x, tr.translation.y, roll_pitch_yaw(tr.rotation)[2]])


def mount(transform_stamped: Any) -> dict[str, float]:
    """A LiDAR's mount (``base_link`` -> sensor) as ``Lidar3DConfig``'s fields: m and deg, z as its height."""
    tr = transform_stamped.transform
    roll, pitch, yaw = np.degrees(roll_pitch_yaw(tr.rotation))
    return {
        "mount_x": round(float(tr.translation.x), 6),
        "mount_y": round(float(tr.translation.y), 6),
        "height": round(float(tr.translation.z), 6),
        "mount_roll_deg": round(float(roll), 4),
        "mount_pitch_deg": round(float(pitch), 4),
        "mount_yaw_deg": round(float(yaw), 4),
    }


def clock(seconds: float) -> Any:
    return ros_types().types["rosgraph_msgs/msg/Clock"](clock=stamp(seconds))
