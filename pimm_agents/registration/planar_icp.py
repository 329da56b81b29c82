"""Point-to-plane ICP for a ground robot: the scan's pose in (x, y, yaw), z, roll and pitch held.

Open3D's ICP rebuilds its search tree of the target on every call and solves all six degrees of freedom;
measured on the iilab (32 000 map points, 1 700 scan points, machine loaded), the tree alone took 49 of its
80 ms per scan. Here the map's tree is built once, each scan costs its own nearest-neighbour queries, and
the solve has the three unknowns a robot on a floor has.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree


class PlanarIcp:
    def __init__(self, points: np.ndarray, normals: np.ndarray) -> None:
        self.points = np.asarray(points, dtype=float)
        self.normals = np.asarray(normals, dtype=float)
        self.tree = cKDTree(self.points)

    def align(
        self, scan: np.ndarray, guess: np.ndarray, max_distance: float, iterations: int, tolerance: float = 1e-4
    ) -> np.ndarray:
        """The pose (x, y, yaw) that puts ``scan`` (M, 3, robot frame, z above the floor) onto the map,
        starting from ``guess``: Gauss-Newton on the point-to-plane distances of pairs closer than
        ``max_distance``, until a step moves less than ``tolerance`` (m and rad)."""
        pose = np.asarray(guess, dtype=float).copy()
        for _ in range(iterations):
            moved = transform(scan, pose)
            distance, nearest = self.tree.query(moved, distance_upper_bound=max_distance)
            paired = np.isfinite(distance)
            if np.count_nonzero(paired) < 6:
                break
            p, q, n = moved[paired], self.points[nearest[paired]], self.normals[nearest[paired]]
            lever = n[:, 1] * (p[:, 0] - pose[0]) - n[:, 0] * (p[:, 1] - pose[1])  # d(n . p) / d yaw
            jacobian = np.stack([n[:, 0], n[:, 1], lever], axis=1)
            residual = np.einsum("ij,ij->i", n, p - q)
            step, *_ = np.linalg.lstsq(jacobian, -residual, rcond=None)
            pose += step
            if np.abs(step).max() < tolerance:
                break
        return pose

    def covariance(self, scan: np.ndarray, pose: np.ndarray, max_distance: float) -> np.ndarray | None:
        """The Gauss-Newton covariance of ``pose`` (x, y, yaw): s^2 (J^T J)^-1 over the point-to-plane pairs
        closer than ``max_distance``, s^2 their residuals' variance; None with fewer than 6 pairs. Along a
        direction the map's planes do not constrain (a corridor's axis) it is large, as it should be."""
        moved = transform(scan, pose)
        distance, nearest = self.tree.query(moved, distance_upper_bound=max_distance)
        paired = np.isfinite(distance)
        if np.count_nonzero(paired) < 6:
            return None
        p, q, n = moved[paired], self.points[nearest[paired]], self.normals[nearest[paired]]
        lever = n[:, 1] * (p[:, 0] - pose[0]) - n[:, 0] * (p[:, 1] - pose[1])
        jacobian = np.stack([n[:, 0], n[:, 1], lever], axis=1)
        residual = np.einsum("ij,ij->i", n, p - q)
        variance = float(residual @ residual) / max(1, len(residual) - 3)
        return variance * np.linalg.pinv(jacobian.T @ jacobian)

    def fitness(self, scan: np.ndarray, pose: np.ndarray, distance: float) -> float:
        """Share of the scan's points within ``distance`` of a map point at ``pose``."""
        d, _ = self.tree.query(transform(scan, pose), distance_upper_bound=distance)
        return float(np.mean(np.isfinite(d))) if len(d) else 0.0


def transform(points: np.ndarray, pose: np.ndarray) -> np.ndarray:
    """Robot-frame points (M, 3) into the map frame at a planar pose."""
    c, s = np.cos(pose[2]), np.sin(pose[2])
    out = points.copy()
    out[:, 0] = c * points[:, 0] - s * points[:, 1] + pose[0]
    out[:, 1] = s * points[:, 0] + c * points[:, 1] + pose[1]
    return out
