"""The env's observation pieces as ROS 2 messages and back (``rosbags``' typestore: no ROS needed).

- ``/points``: ``sensor_msgs/PointCloud2``, organized (one row per ring, one column per azimuth), x/y/z
  float32, NaN where a ray returned nothing (``is_dense`` false); read back, any cloud with float32 x/y/z
  fields works (other fields, ring or intensity, are skipped).
- ``/scan``: ``sensor_msgs/LaserScan``, no return = +inf (REP 117).
- ``/odom`` (frame ``odom`` -> ``base_link``) and ``/ground_truth`` (``map`` -> ``base_link``):
  ``nav_msgs/Odometry``; frames per REP 105.
- ``/events``: ``std_msgs/String``, ``kidnap`` when the robot was kidnapped.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from pimm_env.errors import BagError

TOPICS = {"points": "/points", "scan": "/scan", "odom": "/odom", "truth": "/ground_truth", "events": "/events"}
TYPES = {
    "/points": "sensor_msgs/msg/PointCloud2",
    "/scan": "sensor_msgs/msg/LaserScan",
    "/odom": "nav_msgs/msg/Odometry",
    "/ground_truth": "nav_msgs/msg/Odometry",
    "/events": "std_msgs/msg/String",
}
KIDNAP = "kidnap"
_FLOAT32 = 7  # sensor_msgs/PointField FLOAT32


def typestore():
    from rosbags.typesys import Stores, get_typestore

    return get_typestore(Stores.ROS2_HUMBLE)


def nanoseconds(seconds: float) -> int:
    return round(seconds * 1e9)


def time_stamp(store, seconds: float):
    """``builtin_interfaces/Time`` of ``seconds`` (from 0: a stamp is never negative)."""
    ns = max(0, nanoseconds(seconds))
    return store.types["builtin_interfaces/msg/Time"](sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)


def header(store, seconds: float, frame: str):
    return store.types["std_msgs/msg/Header"](stamp=time_stamp(store, seconds), frame_id=frame)


def seconds_of(stamp: Any) -> float:
    """A ``builtin_interfaces/Time`` in seconds."""
    return stamp.sec + stamp.nanosec * 1e-9


def stamp_seconds(msg: Any) -> float:
    return seconds_of(msg.header.stamp)


def odometry(store, seconds: float, pose: np.ndarray, frame: str, child: str = "base_link"):
    """A planar pose as ``nav_msgs/Odometry`` (z 0, yaw as a quaternion about z; no twist, no covariance)."""
    t = store.types
    x, y, yaw = (float(v) for v in pose)
    position = t["geometry_msgs/msg/Point"](x=x, y=y, z=0.0)
    orientation = t["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=float(np.sin(yaw / 2)), w=float(np.cos(yaw / 2)))
    pose_msg = t["geometry_msgs/msg/PoseWithCovariance"](
        pose=t["geometry_msgs/msg/Pose"](position=position, orientation=orientation), covariance=np.zeros(36)
    )
    zero = t["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.0)
    twist = t["geometry_msgs/msg/TwistWithCovariance"](
        twist=t["geometry_msgs/msg/Twist"](linear=zero, angular=zero), covariance=np.zeros(36)
    )
    return t["nav_msgs/msg/Odometry"](header=header(store, seconds, frame), child_frame_id=child, pose=pose_msg,
                                      twist=twist)  # fmt: skip


def expect_type(msg: Any, fields: tuple[str, ...], kind: str, where: str) -> None:
    """A ``BagError`` naming ``where`` and the message's type unless ``msg`` has ``fields`` (it is a ``kind``)."""
    if not all(hasattr(msg, name) for name in fields):
        raise BagError(f"{where}: a {type(msg).__name__} is not a {kind}; name a topic of that type")


def planar_pose(msg: Any, where: str = "message") -> np.ndarray:
    """(x, y, yaw) of a pose message: ``nav_msgs/Odometry``, ``geometry_msgs/PoseWithCovarianceStamped``,
    ``PoseStamped``, ``Pose`` or ``TransformStamped``; any other type is a ``BagError`` naming ``where``."""
    pose = getattr(msg, "pose", None)
    pose = getattr(pose, "pose", pose)  # Odometry and PoseWithCovarianceStamped wrap the Pose once more
    if pose is not None and hasattr(pose, "position") and hasattr(pose, "orientation"):
        p, q = pose.position, pose.orientation
    elif hasattr(msg, "position") and hasattr(msg, "orientation"):  # a bare Pose
        p, q = msg.position, msg.orientation
    elif hasattr(getattr(msg, "transform", None), "translation"):  # TransformStamped
        p, q = msg.transform.translation, msg.transform.rotation
    else:
        kind = type(msg).__name__
        raise BagError(
            f"{where}: a {kind} holds no pose; give a topic of nav_msgs/Odometry, geometry_msgs/PoseStamped,"
            " PoseWithCovarianceStamped or TransformStamped"
        )
    # the yaw of the quaternion whatever its length (some drivers do not normalize); one of no length has no
    # yaw: NaN, which the readers set aside and count as they do any value that is not finite
    norm = q.w**2 + q.x**2 + q.y**2 + q.z**2
    if abs(norm - 1.0) < 1e-6:  # a unit quaternion, as nearly every message holds
        yaw = np.arctan2(2 * (q.w * q.z + q.x * q.y), 1 - 2 * (q.y**2 + q.z**2))
    else:
        yaw = np.arctan2(2 * (q.w * q.z + q.x * q.y), q.w**2 + q.x**2 - q.y**2 - q.z**2) if norm > 1e-12 else np.nan
    return np.array([p.x, p.y, yaw])


def laser_scan(store, seconds: float, ranges: np.ndarray, angles: np.ndarray, lidar) -> Any:
    """The 2D scan as ``sensor_msgs/LaserScan``; beams at ``max_range`` (no return) become +inf."""
    ranges = np.asarray(ranges, dtype=np.float32).copy()
    ranges[ranges >= lidar.max_range] = np.inf
    increment = float(angles[1] - angles[0]) if len(angles) > 1 else 0.0
    return store.types["sensor_msgs/msg/LaserScan"](
        header=header(store, seconds, "base_scan"),
        angle_min=float(angles[0]),
        angle_max=float(angles[-1]),
        angle_increment=increment,
        time_increment=0.0,
        scan_time=float(1.0 / lidar.rate_hz),
        range_min=float(lidar.min_range),
        range_max=float(lidar.max_range),
        ranges=ranges,
        intensities=np.zeros(0, dtype=np.float32),
    )


def scan_ranges(msg: Any, beams: int, max_range: float, where: str) -> np.ndarray:
    """The ranges of a LaserScan as the env gives them (no return = ``max_range``, beams counter-clockwise: a
    scan with a negative ``angle_increment`` is reversed); checks the beam count against the message's own
    angles and against the layout expected."""
    expect_type(msg, ("ranges", "angle_increment", "angle_min", "angle_max"), "sensor_msgs/LaserScan", where)
    ranges = np.asarray(msg.ranges, dtype=np.float32)
    if msg.angle_increment < 0:
        ranges = ranges[::-1]
    if msg.angle_increment != 0:
        implied = round((msg.angle_max - msg.angle_min) / msg.angle_increment) + 1
        if implied != len(ranges):
            raise BagError(f"{where}: {len(ranges)} ranges, but angle_min/max/increment imply {implied}")
    if len(ranges) != beams:
        raise BagError(f"{where}: {len(ranges)} beams, the 2D LiDAR layout expects {beams} (see --sensors)")
    out = ranges.copy()
    out[~np.isfinite(out) | (out >= max_range) | (out < msg.range_min)] = max_range
    return out


def point_cloud(store, seconds: float, cloud: np.ndarray, mask: np.ndarray, rings: int) -> Any:
    """The 3D cloud (sensor frame) as an organized PointCloud2, NaN where nothing returned."""
    t = store.types
    points = np.asarray(cloud, dtype=np.float32).copy()
    points[~np.asarray(mask, dtype=bool)] = np.nan
    width = len(points) // rings
    fields = [t["sensor_msgs/msg/PointField"](name=n, offset=4 * i, datatype=_FLOAT32, count=1)
              for i, n in enumerate("xyz")]  # fmt: skip
    return t["sensor_msgs/msg/PointCloud2"](
        header=header(store, seconds, "lidar"),
        height=rings,
        width=width,
        fields=fields,
        is_bigendian=False,
        point_step=12,
        row_step=12 * width,
        data=points.view(np.uint8).reshape(-1),
        is_dense=False,
    )


#: sensor_msgs/PointField datatypes as numpy types
FIELD_TYPES = {
    1: np.int8,
    2: np.uint8,
    3: np.int16,
    4: np.uint16,
    5: np.int32,
    6: np.uint32,
    7: np.float32,
    8: np.float64,
}


def point_rows(msg: Any, where: str) -> np.ndarray:
    """A PointCloud2's data as (points, point_step) bytes, checked against its size."""
    if msg.is_bigendian:
        raise BagError(f"{where}: big-endian PointCloud2 is not supported")
    count = msg.width * msg.height
    raw = np.asarray(msg.data, dtype=np.uint8)
    if len(raw) < count * msg.point_step:
        raise BagError(f"{where}: {len(raw)} data bytes, {count} points of {msg.point_step} bytes need more")
    return raw[: count * msg.point_step].reshape(count, msg.point_step)


def field_of(msg: Any, rows: np.ndarray, name: str) -> np.ndarray | None:
    """One numeric field (x, ring, ...) of every point, from ``point_rows``; None if the cloud has no such field."""
    field = next((f for f in msg.fields if f.name == name), None)
    if field is None or field.datatype not in FIELD_TYPES:
        return None
    dtype = np.dtype(FIELD_TYPES[field.datatype])
    return rows[:, field.offset : field.offset + dtype.itemsize].copy().view(dtype).reshape(-1)


def cloud_points(msg: Any, where: str) -> np.ndarray:
    """(N, 3) float32 x/y/z of a PointCloud2 of any field layout, NaN rows kept (no return)."""
    expect_type(msg, ("fields", "point_step", "data", "width", "height"), "sensor_msgs/PointCloud2", where)
    offsets = {f.name: f for f in msg.fields}
    missing = [n for n in "xyz" if n not in offsets]
    if missing:
        raise BagError(f"{where}: PointCloud2 has no field(s) {missing} (fields: {sorted(offsets)})")
    if any(offsets[n].datatype != _FLOAT32 for n in "xyz"):
        raise BagError(f"{where}: PointCloud2 x/y/z must be float32")
    beyond = [n for n in "xyz" if offsets[n].offset + 4 > msg.point_step]
    if beyond:
        raise BagError(
            f"{where}: PointCloud2 field(s) {beyond} at offset(s) {[offsets[n].offset for n in beyond]} do not fit "
            f"its point_step {msg.point_step}"
        )
    rows = point_rows(msg, where)
    columns: list[np.ndarray] = []
    for name in "xyz":
        column = field_of(msg, rows, name)
        assert column is not None  # checked above: float32 x, y and z exist
        columns.append(column)
    return np.column_stack(columns)
