"""Plane extraction by repeated RANSAC (Open3D's ``segment_plane``): the dominant plane, its inliers
removed, then the next (thesis 3.3.1)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class PlaneParams:
    max_planes: int = 20
    distance_threshold: float = 0.20
    min_inliers: int = 150
    iterations: int = 100


@dataclass(frozen=True)
class Plane:
    """n . p + d = 0 with |n| = 1, fitted to ``inliers`` (K, 3); ``rms`` is the inliers' RMS distance to it."""

    normal: np.ndarray
    d: float
    inliers: np.ndarray
    rms: float

    @property
    def centroid(self) -> np.ndarray:
        return self.inliers.mean(axis=0)

    def distance(self, points: np.ndarray) -> np.ndarray:
        return np.abs(points @ self.normal + self.d)


def refit(points: np.ndarray) -> tuple[np.ndarray, float, float]:
    """Least-squares plane through ``points``: unit normal, offset and RMS residual.

    The normal is the eigenvector of the 3 x 3 scatter matrix with the smallest eigenvalue, which is the RMS
    residual squared (the same plane as an SVD of the centred points, at a fraction of the cost).
    """
    centroid = points.mean(axis=0)
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
        sigma = 1.4826 * float(np.median(residual))
        inside = residual <= max(3.0 * sigma, 0.01)
        if inside.sum() < 3 or inside.sum() == len(kept):
            break
        kept = points[inside]
        normal, d, rms = refit(kept)
    return normal, d, rms, kept


def extract_planes(points: np.ndarray, params: PlaneParams, seed: int = 0) -> list[Plane]:
    """Up to ``max_planes`` planes with at least ``min_inliers`` inliers each, largest first.

    Each RANSAC model is refitted to its inliers by trimmed least squares (:func:`robust_refit`).
    Open3D's RANSAC has its own generator, seeded here so that a scan always gives the same planes.
    """
    import open3d as o3d

    points = np.asarray(points, dtype=float)
    points = points[np.all(np.isfinite(points), axis=1)]
    o3d.utility.random.seed(seed)
    planes: list[Plane] = []
    remaining = points
    while len(planes) < params.max_planes and len(remaining) >= params.min_inliers:
        cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(remaining))
        _, index = cloud.segment_plane(params.distance_threshold, 3, params.iterations)
        if len(index) < params.min_inliers:
            break
        normal, d, rms, inliers = robust_refit(remaining[index])
        planes.append(Plane(normal, d, inliers, rms))
        keep = np.ones(len(remaining), dtype=bool)
        keep[index] = False
        remaining = remaining[keep]
    return planes
