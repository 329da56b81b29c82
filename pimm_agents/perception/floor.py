"""The floor under a scan: how high the sensor sits above it and how far the sensor leans, from the scan alone.

A scan's floor is the lowest well-filled level surface below the sensor (desk tops and seats are level too,
but higher; see :func:`estimate_floor`). Its distance from the sensor is the mount height; its normal gives the
rotation that levels the scan (the sensor's roll and pitch).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pimm_env.errors import PerceptionError
from pimm_env.geometry import rotation_onto_z


@dataclass(frozen=True)
class FloorConfig:
    """Ours; sized for indoor scans with the sensor 0.2-1.8 m up and leaning at most a few degrees."""

    distance_m: float = 0.03  # an inlier lies this close to the plane
    hypotheses: int = 1500
    score_points: int = 3000  # hypotheses are scored on at most this many of the candidate returns
    max_tilt_deg: float = 7.0  # a level hypothesis's normal within this of the sensor's z (the mount leans up to 5 deg)
    min_share: float = 0.1  # the floor's height bin holds at least this share of the fullest bin's returns
    min_inliers: int = 50
    below_m: float = 0.1  # candidates: returns at least this far below the sensor
    refits: int = 3  # least-squares refits of the floor, each on the returns near the last
    broad_m: float = 0.3  # a floor whose returns spread this much (std, m) both ways tilts on its own fit


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


def estimate_floor(points: np.ndarray, config: FloorConfig = FloorConfig(), seed: int = 0) -> Floor:
    """The floor under the scan ``points`` (N, 3, sensor frame); an error says when none can be found.

    Two steps. Up: RANSAC of level planes only (through three random returns, the normal within
    ``max_tilt_deg`` of the sensor's z, scored on up to ``score_points`` returns); the best plane, floor or
    ceiling, refitted by least squares, gives the direction of up, which every level surface shares. Floor:
    the heights of the returns below the sensor along that direction, in 2 cm bins; the lowest height that
    holds at least ``min_share`` of the fullest bin's returns (and ``min_inliers``) is the floor, refitted to
    its returns. Desk tops and seats are level too, but above it. A scan that sees no floor (a narrow field
    mounted high in a small room) finds a desk top instead: give the height then."""
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    points = points[np.isfinite(points).all(axis=1)]
    rng = np.random.default_rng(seed)
    below = points[points[:, 2] < -config.below_m]
    if len(below) < config.min_inliers:
        raise PerceptionError(
            f"only {len(below)} returns lie below the sensor: no floor to measure the mount height from; "
            "give the sensor's height above the floor (--sensor-height)"
        )
    up = _up(points, config, rng)
    heights = below @ up
    bins = np.floor((heights - heights.min()) / 0.02).astype(np.int64)
    counts = np.bincount(bins)
    counts = counts + np.concatenate([[0], counts[:-1]]) + np.concatenate([counts[1:], [0]])  # 6 cm windows
    enough = np.flatnonzero((counts >= config.min_share * counts.max()) & (counts >= config.min_inliers))
    if len(enough) == 0:
        raise PerceptionError("no level surface below the sensor: cannot find the floor; give --sensor-height")
    level = heights.min() + 0.02 * (enough[0] + 0.5)
    inliers = below[np.abs(heights - level) <= config.distance_m]
    normal, centre = up, inliers.mean(axis=0)
    for _ in range(config.refits):  # least squares, then again on the returns within reach of that plane
        fitted, spread = _plane_fit(inliers, centre)
        broad = spread >= config.broad_m  # a floor, not a strip, to tilt on
        if not broad and np.degrees(np.arccos(min(1.0, float(fitted @ up)))) > 2.0:
            break
        normal = fitted
        near = below[np.abs((below - centre) @ normal) <= config.distance_m]
        if len(near) < config.min_inliers:
            break
        inliers, centre = near, near.mean(axis=0)
    return Floor(height=float(-(centre @ normal)), normal=normal, inliers=len(inliers))


def _plane_fit(points: np.ndarray, centre: np.ndarray) -> tuple[np.ndarray, float]:
    """The least-squares plane's upward unit normal through ``centre``, and the points' spread (std, m) along
    its narrower in-plane axis."""
    _, spread, axes = np.linalg.svd(points - centre, full_matrices=False)
    normal = axes[2] if axes[2][2] > 0 else -axes[2]
    return normal, float(spread[1] / np.sqrt(len(points)))


def _up(points: np.ndarray, config: FloorConfig, rng: np.random.Generator) -> np.ndarray:
    """The normal of the scan's best-supported level plane, refitted to its inliers (and to those of the refit:
    a small dense patch, a desk top, leaves the first fit free to lean; the walls it cuts then level it)."""
    scored = points[rng.choice(len(points), min(len(points), config.score_points), replace=False)]
    a, b, c = (scored[rng.integers(0, len(scored), config.hypotheses)] for _ in range(3))
    normal = np.cross(b - a, c - a)
    length = np.linalg.norm(normal, axis=1)
    normal = normal / np.maximum(length, 1e-12)[:, None]
    normal *= np.where(normal[:, 2] < 0, -1.0, 1.0)[:, None]
    level = (length > 1e-9) & (normal[:, 2] >= np.cos(np.radians(config.max_tilt_deg)))
    if not level.any():
        raise PerceptionError("no level surface in the scan: cannot find the floor; give --sensor-height")
    normal, offset = normal[level], -np.einsum("ij,ij->i", normal[level], a[level])
    counts = (np.abs(scored @ normal.T + offset) <= config.distance_m).sum(axis=0)
    best = int(np.argmax(counts))
    normal, point = normal[best], a[level][best]
    for _ in range(config.refits):  # least squares on the inliers, again on those of the refitted plane
        inliers = points[np.abs((points - point) @ normal) <= config.distance_m]
        if len(inliers) < 3:
            break
        point = inliers.mean(axis=0)
        normal = _plane_fit(inliers, point)[0]
    return normal
