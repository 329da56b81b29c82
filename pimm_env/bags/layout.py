"""A bag's LiDAR layouts read from its own messages, and a point cloud placed into a layout's grid.

- 2D, from the first ``sensor_msgs/LaserScan``: beams, angle_min / angle_max (a scan whose beams close the circle
  is a full circle), range_min / range_max, and the rate from ``scan_time``.
- 3D, from the first ``sensor_msgs/PointCloud2``: rings are the rows of an organized cloud, or the values of its
  ``ring`` field; columns are the points per ring; the vertical field is the spread of the rings' median
  elevations, which must be evenly spaced and centred on the horizon (what ``Lidar3DConfig`` describes). An
  unorganized cloud without a ring field (a driver or a conversion that dropped it) has its rings read from
  its returns' elevations, which a spinning LiDAR's returns take at a few discrete values, and its columns
  from the azimuth step within a ring (``layout_from_angles``); a cloud whose elevations form no evenly
  spaced rings (a non-repetitive or solid-state pattern) is refused with what to give instead.
  Range and rate are not in the message: the rate comes from the first two clouds' stamps, the range is the
  thesis's unless the cloud reaches further.

The mount offsets are not read (no ``/tf_static``): a sensor off the robot's centre needs a sensors file.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from pimm_env.bags.bag_file import open_bag
from pimm_env.bags.messages import cloud_points, expect_type, field_of, point_rows, stamp_seconds
from pimm_env.errors import BagError
from pimm_env.sim.lidar import Lidar2DConfig, Lidar3DConfig, elevations_3d


def returns(points: np.ndarray) -> np.ndarray:
    """Which points are returns: finite and not at the sensor (drivers mark no return with NaN, as ours, or
    with zeros, as Ouster's)."""
    return np.all(np.isfinite(points), axis=1) & np.any(points != 0, axis=1)


def scan_layout(msg: Any, where: str) -> Lidar2DConfig:
    """The 2D LiDAR a LaserScan describes. A negative ``angle_increment`` (beams clockwise, as from a LiDAR
    mounted upside down) is read as the same beams counter-clockwise; ``scan_ranges`` reverses them to match."""
    expect_type(msg, ("ranges", "angle_increment", "angle_min", "angle_max"), "sensor_msgs/LaserScan", where)
    beams = len(msg.ranges)
    increment = float(msg.angle_increment)
    if beams < 1 or (beams > 1 and increment == 0):
        raise BagError(f"{where}: {beams} ranges with angle_increment {increment}: no layout to read")
    first, last = (msg.angle_min, msg.angle_max) if increment >= 0 else (msg.angle_max, msg.angle_min)
    increment = abs(increment)
    # the message's float32 fields, rounded back to the decimals they were written with (-180 deg, not
    # -180.000005): a layout read from a bag then gives the same bearings as the one it was recorded with
    low = round(float(np.degrees(first)), 4)
    span = float(np.degrees(increment)) * beams
    full_circle = abs(span - 360.0) < 0.5 * float(np.degrees(increment))
    high = low + 360.0 if full_circle else round(float(np.degrees(last)), 4)
    rate = round(1.0 / msg.scan_time, 3) if msg.scan_time > 0 else Lidar2DConfig().rate_hz
    try:
        return Lidar2DConfig(
            beams=beams,
            angle_min_deg=low,
            angle_max_deg=high,
            min_range=round(float(msg.range_min), 4),
            max_range=round(float(msg.range_max), 4),
            rate_hz=float(rate),
        )
    except ValueError as error:
        raise BagError(f"{where}: {error}") from None


def ring_of_points(msg: Any, count: int, where: str) -> np.ndarray | None:
    """Each point's ring: its row in an organized cloud, else its ``ring`` field; None when it has neither."""
    if msg.height > 1:
        return np.repeat(np.arange(msg.height), msg.width)
    rings = field_of(msg, point_rows(msg, where), "ring")
    return None if rings is None else rings.astype(np.int64)[:count]


def cloud_layout(msg: Any, points: np.ndarray, where: str) -> Lidar3DConfig:
    """The 3D LiDAR a PointCloud2 (and its x/y/z ``points``) describes."""
    rings = ring_of_points(msg, len(points), where)
    if rings is None:
        return layout_from_angles(points, where)
    layers = int(rings.max()) + 1 if len(rings) else 0
    if layers < 2 or len(points) % layers:
        raise BagError(f"{where}: {len(points)} points in {layers} rings is not a grid of rings x columns")
    returned = returns(points)
    elevation = np.arctan2(points[:, 2], np.hypot(points[:, 0], points[:, 1]))
    medians = np.full(layers, np.nan)
    for ring in np.unique(rings[returned]):
        medians[ring] = np.median(elevation[returned & (rings == ring)])
    if np.isnan(medians).any():
        raise BagError(f"{where}: rings {np.flatnonzero(np.isnan(medians)).tolist()} have no return to measure")
    return _ring_layout(np.sort(medians), len(points) // layers, points[returned], where)


#: Returns whose elevations lie closer than this belong to one ring (rad); a spinning LiDAR's rings are at
#: least 0.3 deg apart (a 128-ring one over 45 deg), and a ring's returns share one elevation to far less.
RING_GAP = np.radians(0.1)
#: Fewest returns a ring of a cloud without a ring field must hold: fewer, and the elevations are not rings.
MIN_RING_RETURNS = 8
NO_RINGS = (
    "give the 3D LiDAR with --sensors (a preset or a sensors .yaml file) to place its points into that layout's "
    "grid, or segment single clouds with `evaluate.py segment`, which reads any point set"
)


def layout_from_angles(points: np.ndarray, where: str) -> Lidar3DConfig:
    """The spinning LiDAR an unorganized cloud without a ring field came from: rings where its returns'
    elevations cluster (gaps wider than ``RING_GAP`` between them), evenly spaced about the horizon; columns
    from the median azimuth step between neighbouring returns of a ring. Refuses a cloud whose elevations form
    no such rings, saying what to give instead."""
    returned = points[returns(points)]
    if len(returned) < 2 * MIN_RING_RETURNS:
        raise BagError(f"{where}: {len(returned)} returns in a cloud without a ring field are too few to read its "
                       f"rings from; {NO_RINGS}")  # fmt: skip
    horizontal = np.hypot(returned[:, 0], returned[:, 1])
    elevation = np.arctan2(returned[:, 2], horizontal)
    order = np.argsort(elevation, kind="stable")
    ring_of = np.zeros(len(returned), dtype=np.int64)
    ring_of[order] = np.concatenate([[0], np.cumsum(np.diff(elevation[order]) > RING_GAP)])
    counts = np.bincount(ring_of)
    if len(counts) < 2 or counts.min() < MIN_RING_RETURNS:
        raise BagError(
            f"{where}: an unorganized PointCloud2 without a ring field whose returns' elevations form no rings "
            f"({len(counts)} clusters, the smallest of {counts.min()} returns: a non-repetitive or solid-state "
            f"pattern?); {NO_RINGS}"
        )
    azimuth = np.arctan2(returned[:, 1], returned[:, 0])
    medians, steps = np.empty(len(counts)), np.empty(len(counts))
    ends = np.cumsum(counts)
    for ring, (start, end) in enumerate(zip(ends - counts, ends, strict=True)):  # a ring: a run of ``order``
        members = order[start:end]
        medians[ring] = np.median(elevation[members])
        step = np.diff(np.sort(azimuth[members]))
        steps[ring] = np.median(step[step > 1e-6]) if (step > 1e-6).any() else np.inf
    columns = round(2 * np.pi / float(np.median(steps)))
    if columns < 2:
        raise BagError(f"{where}: the rings of a cloud without a ring field hold returns at one azimuth; {NO_RINGS}")
    return _ring_layout(medians, columns, returned, where)


def _ring_layout(medians: np.ndarray, columns: int, returned: np.ndarray, where: str) -> Lidar3DConfig:
    """The layout of rings at ``medians`` (rad, lowest first) with ``columns`` points each, which must be evenly
    spaced about the horizon; its range reaches the farthest of the ``returned`` points."""
    layers = len(medians)
    spacing = (medians[-1] - medians[0]) / (layers - 1)
    even = np.abs(medians - np.linspace(medians[0], medians[-1], layers)).max() <= spacing / 2
    centred = abs(medians[0] + medians[-1]) / 2 <= spacing / 2
    if not (even and centred):
        raise BagError(
            f"{where}: rings from {np.degrees(medians[0]):.1f} to {np.degrees(medians[-1]):.1f} deg are not evenly "
            "spaced about the horizon, which is the only 3D layout this project models"
        )
    fov = round(float(np.degrees(medians[-1] - medians[0])), 1)
    reach = float(np.hypot(returned[:, 0], returned[:, 1]).max()) if len(returned) else 0.0  # in the floor plane
    max_range = max(Lidar3DConfig().max_range, float(np.ceil(reach)))
    return Lidar3DConfig(layers=layers, points_per_layer=columns, vertical_fov_deg=fov, max_range=max_range)


def layouts_from_bag(path: Path, scan_topic: str | None, points_topic: str | None) -> tuple[Any, Any]:
    """(Lidar3DConfig or None, Lidar2DConfig or None) from the first messages on those topics."""
    with open_bag(Path(path)) as reader:
        have = {c.topic: c for c in reader.connections}
        lidar2d = lidar3d = None
        if scan_topic in have:
            for connection, _, raw in reader.messages(connections=[have[scan_topic]]):
                lidar2d = scan_layout(reader.deserialize(raw, connection.msgtype), f"{path}: {scan_topic} message 0")
                break
        if points_topic in have:
            stamps = []
            for connection, _, raw in reader.messages(connections=[have[points_topic]]):
                msg = reader.deserialize(raw, connection.msgtype)
                if lidar3d is None:
                    where = f"{path}: {points_topic} message 0"
                    lidar3d = cloud_layout(msg, cloud_points(msg, where), where)
                stamps.append(stamp_seconds(msg))
                if len(stamps) == 2:
                    break
            if lidar3d is not None and len(stamps) == 2 and stamps[1] > stamps[0]:
                lidar3d = replace(lidar3d, rate_hz=round(1.0 / (stamps[1] - stamps[0]), 3))
        if lidar2d is None and lidar3d is None:
            listed = ", ".join(f"{t} ({c.msgtype})" for t, c in sorted(have.items()))
            raise BagError(
                f"{path}: no LiDAR to read: the scan topic {scan_topic!r} and the cloud topic {points_topic!r} have"
                f" no messages here; the bag has {listed or 'no topics'} (name them with --scan-topic,"
                " --points-topic)"
            )
    return lidar3d, lidar2d


def organize(points: np.ndarray, layout: Lidar3DConfig, where: str) -> tuple[np.ndarray, np.ndarray]:
    """The cloud in ``layout``'s grid (rings from the lowest, columns from azimuth -pi), whatever order the
    points came in (top ring first, another azimuth origin, unorganized): each returned point goes to the
    nearest ray by elevation and azimuth, the nearer return where two share one. Refuses a cloud that does
    not fit the layout (fewer than 90 % of its returns placed) rather than dropping points silently."""
    n = layout.num_points
    cloud, mask = np.zeros((n, 3), np.float32), np.zeros(n, np.int8)
    points = np.asarray(points, dtype=np.float32)
    p = points[returns(points)]
    if not len(p):
        return cloud, mask
    horizontal = np.hypot(p[:, 0], p[:, 1])
    elevation, azimuth = np.arctan2(p[:, 2], horizontal), np.arctan2(p[:, 1], p[:, 0])
    rings = elevations_3d(layout)
    spacing = float(rings[1] - rings[0]) if layout.layers > 1 else np.inf
    ring = np.zeros(len(p), dtype=np.int64) if layout.layers == 1 else np.rint((elevation - rings[0]) / spacing)
    ring = np.asarray(ring, dtype=np.int64)
    inside = (ring >= 0) & (ring < layout.layers)
    inside &= np.abs(elevation - rings[np.clip(ring, 0, layout.layers - 1)]) <= spacing / 2 + 1e-6
    step = 2 * np.pi / layout.points_per_layer
    column = np.rint((azimuth + np.pi) / step).astype(np.int64) % layout.points_per_layer
    index = ring * layout.points_per_layer + column
    order = np.argsort(-np.hypot(horizontal, p[:, 2])[inside], kind="stable")  # far first: the nearer one stays
    cells, values = index[inside][order], p[inside][order]
    cloud[cells], mask[cells] = values, 1
    placed = int(mask.sum())
    if placed < 0.9 * len(p):
        raise BagError(
            f"{where}: only {placed} of {len(p)} returns fit the 3D LiDAR layout ({layout.layers} rings x "
            f"{layout.points_per_layer} over {layout.vertical_fov_deg} deg): see --sensors"
        )
    return cloud, mask
