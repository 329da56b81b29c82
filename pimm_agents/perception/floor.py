"""The floor under a scan: how high the sensor sits above it and how far the sensor leans, from the scan alone.

A scan's floor is the lowest large level plane below the sensor (desk tops and seats are level too, but
higher). RANSAC planes are taken one after another from the returns below the sensor (Open3D's
``segment_plane``, seeded); of those within ``max_tilt_deg`` of level and holding at least ``min_share`` of the
largest one's points, the lowest is the floor. Its distance from the sensor is the mount height; its normal
gives the rotation that levels the scan (the sensor's roll and pitch).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pimm_env.errors import PerceptionError


@dataclass(frozen=True)
class FloorConfig:
    """Ours; sized for indoor scans with the sensor 0.2-1.8 m up and leaning at most a few degrees."""

    voxel_m: float = 0.05  # the returns are thinned to one per voxel first
    distance_m: float = 0.03  # a RANSAC inlier lies this close to the plane
    max_planes: int = 6
    max_tilt_deg: float = 15.0  # a floor candidate's normal within this of the sensor's z
    min_share: float = 0.3  # of the largest level plane's inliers
    min_inliers: int = 50
    below_m: float = 0.1  # candidates: returns at least this far below the sensor
    iterations: int = 200


@dataclass(frozen=True)
class Floor:
    height: float  # the sensor above the floor (m)
    normal: np.ndarray  # the floor's upward unit normal in the sensor's frame
    inliers: int

    @property
    def tilt_deg(self) -> float:
        return float(np.degrees(np.arccos(np.clip(self.normal[2], -1.0, 1.0))))

    @property
    def leveling(self) -> np.ndarray:
        """The rotation R that turns the floor's normal onto +z: R @ p is the point in a level sensor frame."""
        return rotation_onto_z(self.normal)


def rotation_onto_z(normal: np.ndarray) -> np.ndarray:
    """The smallest rotation that takes the unit vector ``normal`` onto (0, 0, 1) (Rodrigues)."""
    n = np.asarray(normal, dtype=float) / np.linalg.norm(normal)
    axis = np.cross(n, [0.0, 0.0, 1.0])
    s, c = np.linalg.norm(axis), float(n[2])
    if s < 1e-12:
        return np.eye(3) if c > 0 else np.diag([1.0, -1.0, -1.0])
    k = axis / s
    skew = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + s * skew + (1 - c) * skew @ skew


def estimate_floor(points: np.ndarray, config: FloorConfig = FloorConfig(), seed: int = 0) -> Floor:
    """The floor under the scan ``points`` (N, 3, sensor frame); an error says when none can be found."""
    import open3d as o3d

    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    below = points[np.isfinite(points).all(axis=1) & (points[:, 2] < -config.below_m)]
    cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(below)).voxel_down_sample(config.voxel_m)
    remaining = np.asarray(cloud.points)
    if len(remaining) < config.min_inliers:
        raise PerceptionError(
            f"only {len(remaining)} returns lie below the sensor: no floor to measure the mount height from; "
            "give the sensor's height above the floor (--sensor-height)"
        )
    o3d.utility.random.seed(seed)
    level: list[tuple[float, np.ndarray, int]] = []
    for _ in range(config.max_planes):
        if len(remaining) < config.min_inliers:
            break
        part = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(remaining))
        model, inliers = part.segment_plane(config.distance_m, 3, config.iterations)
        if len(inliers) < config.min_inliers:
            break
        normal, offset = np.asarray(model[:3], dtype=float), float(model[3])
        scale = float(np.linalg.norm(normal))
        normal, offset = normal / scale, offset / scale
        if normal[2] < 0:
            normal, offset = -normal, -offset
        if np.degrees(np.arccos(min(1.0, normal[2]))) <= config.max_tilt_deg and offset > 0:
            level.append((offset, normal, len(inliers)))  # n . p + offset = 0: the sensor is offset above it
        remaining = np.delete(remaining, inliers, axis=0)
    if not level:
        raise PerceptionError(
            "no level plane below the sensor: cannot find the floor; give the sensor's height (--sensor-height)"
        )
    largest = max(count for _, _, count in level)
    offset, normal, count = max(
        (plane for plane in level if plane[2] >= config.min_share * largest), key=lambda p: p[0]
    )
    return Floor(height=offset, normal=normal, inliers=count)
