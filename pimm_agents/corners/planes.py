"""Plane extraction by repeated RANSAC: the dominant plane, its inliers removed, then the next (thesis 3.3.1).

Two RANSACs are offered. Open3D's ``segment_plane`` (the thesis's) draws planes of any orientation. Ours draws
only the orientation the class allows (walls: vertical planes through two points; ceilings: horizontal planes
through one) and scores every hypothesis against every point in one array operation.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from pimm_agents.perception.point_arrays import column_bounds, column_mean, finite_rows
from pimm_env.errors import LocalizerError

#: Plane orientations a RANSAC hypothesis may take.
ORIENTATIONS = ("any", "vertical", "horizontal")
RANSAC_METHODS = ("open3d", "constrained")


@dataclass(frozen=True)
class PlaneParams:
    max_planes: int = 20
    distance_threshold: float = 0.20
    min_inliers: int = 150
    iterations: int = 100
    method: str = "open3d"  # or "constrained": our vectorized RANSAC, hypotheses of the class's orientation
    score_points: int = 1 << 30  # constrained only: hypotheses are scored on at most this many points

    def __post_init__(self) -> None:
        if self.method not in RANSAC_METHODS:
            raise LocalizerError(f"PlaneParams.method {self.method!r}: valid methods are {RANSAC_METHODS}")


@dataclass(frozen=True)
class Plane:
    """n . p + d = 0 with |n| = 1, fitted to ``inliers`` (K, 3); ``rms`` is the inliers' RMS distance to it."""

    normal: np.ndarray
    d: float
    inliers: np.ndarray
    rms: float

    @cached_property
    def centroid(self) -> np.ndarray:
        return column_mean(self.inliers)

    @cached_property
    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Corners of the inliers' axis-aligned box."""
        return column_bounds(self.inliers)

    @cached_property
    def spread(self) -> float:
        """RMS distance of the inliers from their centroid (1 for a degenerate plane)."""
        return float(np.sqrt(np.mean(np.sum((self.inliers - self.centroid) ** 2, axis=1)))) or 1.0

    def nearest_distance(self, point: np.ndarray) -> float:
        """Distance from ``point`` to the nearest inlier."""
        offset = self.inliers - point
        return float(np.sqrt(np.min(np.einsum("ij,ij->i", offset, offset))))

    def box_distance(self, point: np.ndarray) -> float:
        """Distance from ``point`` to the inliers' box: a cheap lower bound on the distance to any inlier."""
        lower, upper = self.bounds
        return float(np.linalg.norm(np.maximum(np.maximum(lower - point, point - upper), 0.0)))

    def distance(self, points: np.ndarray) -> np.ndarray:
        return np.abs(points @ self.normal + self.d)


def refit(points: np.ndarray) -> tuple[np.ndarray, float, float]:
    """Least-squares plane through ``points``: unit normal, offset and RMS residual.

    The normal is the eigenvector of the 3 x 3 scatter matrix with the smallest eigenvalue, which is the RMS
    residual squared (the same plane as an SVD of the centred points, at a fraction of the cost).
    """
    centroid = column_mean(points)
    centred = points - centroid
    values, vectors = np.linalg.eigh(centred.T @ centred / len(points))
    normal = vectors[:, 0]
    rms = float(np.sqrt(max(values[0], 0.0)))
    return normal, float(-normal @ centroid), rms


def robust_refit(points: np.ndarray, rounds: int = 3) -> tuple[np.ndarray, float, float, np.ndarray]:
    """Least-squares plane refitted a few times on the points within 3 robust sigmas of the last fit.

    RANSAC's band (0.2 m by default) also takes in the first 0.2 m of any wall meeting this one; trimming
    them keeps the corner where the two surfaces really meet. Returns normal, offset, RMS and the kept points.
    """
    kept = points
    normal, d, rms = refit(kept)
    for _ in range(rounds):
        residual = np.abs(points @ normal + d)
        sigma = 1.4826 * _median(residual)
        inside = residual <= max(3.0 * sigma, 0.01)
        if inside.sum() < 3 or inside.sum() == len(kept):
            break
        kept = points[inside]
        normal, d, rms = refit(kept)
    return normal, d, rms, kept


def _median(values: np.ndarray) -> float:
    """``np.median`` of a 1-D array by one partition, without its general-purpose overhead."""
    half = len(values) // 2
    if len(values) % 2:
        return float(np.partition(values, half)[half])
    low, high = np.partition(values, (half - 1, half))[half - 1 : half + 1]
    return float((low + high) / 2)


def constrained_ransac(
    points: np.ndarray,
    threshold: float,
    iterations: int,
    orientation: str,
    rng: np.random.Generator,
    score_points: int = 1 << 30,
) -> np.ndarray:
    """Indices of the inliers of the best of ``iterations`` random planes of the given orientation.

    "vertical": the plane through two points' floor projections, standing upright; "horizontal": the level
    plane through one point; "any": the plane through three points. Every hypothesis is scored against every
    point at once, as a (points x hypotheses) array of distances.
    """
    if orientation not in ORIENTATIONS:
        raise LocalizerError(f"orientation {orientation!r}: valid orientations are {ORIENTATIONS}")
    n = len(points)
    if n == 0:
        return np.zeros(0, dtype=np.int64)
    pts = points.astype(np.float32)
    picks = rng.integers(0, n, size=(3, iterations))
    if orientation == "horizontal":
        normals = np.tile(np.array([0.0, 0.0, 1.0], np.float32), (iterations, 1))
    else:
        a, b = pts[picks[0]], pts[picks[1]]
        if orientation == "vertical":
            run = b[:, :2] - a[:, :2]
            normals = np.stack([-run[:, 1], run[:, 0], np.zeros(iterations, np.float32)], axis=1)
        else:
            normals = np.cross(b - a, pts[picks[2]] - a)
    norm = np.linalg.norm(normals, axis=1)
    good = norm > 1e-6  # coincident picks make no plane
    if not good.any():
        return np.zeros(0, dtype=np.int64)
    normals = normals[good] / norm[good, None]
    offsets = -np.einsum("ij,ij->i", normals, pts[picks[0][good]])
    # hypotheses are scored on the first ``score_points`` points (a random subset when the caller shuffled them)
    distance = pts[:score_points] @ normals.T
    distance += offsets
    np.abs(distance, out=distance)
    inside = distance <= threshold
    # summing a bool array along an axis is slow; as bytes into int32 it is four times faster
    best = int(np.argmax(inside.view(np.uint8).sum(axis=0, dtype=np.int32)))
    return np.flatnonzero(np.abs(pts @ normals[best] + offsets[best]) <= threshold)


def extract_planes(points: np.ndarray, params: PlaneParams, seed: int = 0, orientation: str = "any") -> list[Plane]:
    """Up to ``max_planes`` planes with at least ``min_inliers`` inliers each, largest first.

    Each RANSAC model is refitted to its inliers by trimmed least squares (:func:`robust_refit`). Both RANSACs
    are seeded, so that a scan always gives the same planes; ``orientation`` steers the constrained one only.
    """
    points = np.asarray(points, dtype=float)
    points = points[finite_rows(points)]
    if params.method == "open3d":
        import open3d as o3d

        o3d.utility.random.seed(seed)
    rng = np.random.default_rng(seed)
    planes: list[Plane] = []
    remaining = points
    while len(planes) < params.max_planes and len(remaining) >= params.min_inliers:
        if params.method == "constrained":
            index = constrained_ransac(
                remaining, params.distance_threshold, params.iterations, orientation, rng, params.score_points
            )
        else:
            cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(remaining))
            _, inlier_list = cloud.segment_plane(params.distance_threshold, 3, params.iterations)
            index = np.asarray(inlier_list, dtype=np.int64)
        if len(index) < params.min_inliers:
            break
        normal, d, rms, inliers = robust_refit(remaining[index])
        planes.append(Plane(normal, d, inliers, rms))
        keep = np.ones(len(remaining), dtype=bool)
        keep[index] = False
        remaining = remaining[keep]
    return planes
