"""Clusters of particles in (x, y, theta) bins, and the weighted pose statistics of each (as nav2 reports)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import ndimage
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from pimm_agents.particles.kld import bin_indices


@dataclass(frozen=True)
class PoseCluster:
    weight: float
    mean: np.ndarray  # (x, y, theta)
    covariance: np.ndarray  # 3 x 3


def cluster_labels(poses: np.ndarray, xy_size: float, theta_size: float) -> np.ndarray:
    """A cluster label per pose: particles in bins that touch (26-neighbourhood, theta wraps) share one."""
    ix, iy, it, n_theta = bin_indices(poses, xy_size, theta_size)
    ix -= ix.min()
    iy -= iy.min()
    occupied = np.zeros((ix.max() + 1, iy.max() + 1, n_theta + 1), dtype=bool)
    occupied[ix, iy, it] = True
    occupied[:, :, n_theta] = occupied[:, :, 0]  # theta's last bin also touches the first
    labels, count = ndimage.label(occupied, structure=np.ones((3, 3, 3), dtype=bool))
    # A bin and its copy past the wrap are one bin: join their labels.
    first, copy = labels[:, :, 0].ravel(), labels[:, :, n_theta].ravel()
    pairs = (first > 0) & (copy > 0)
    graph = coo_matrix((np.ones(pairs.sum()), (first[pairs], copy[pairs])), shape=(count + 1, count + 1))
    _, merged = connected_components(graph, directed=False)
    _, compact = np.unique(merged[labels[ix, iy, it]], return_inverse=True)
    return compact


def heaviest_cluster(poses: np.ndarray, weights: np.ndarray, labels: np.ndarray) -> PoseCluster:
    """Weight, weighted mean (circular in theta) and covariance of the cluster with the most weight.

    x and y get their weighted covariance; theta the circular variance -2 ln R, R the mean resultant length.
    """
    total = np.bincount(labels, weights)
    best = int(np.argmax(total))
    members = labels == best
    p, w = poses[members], weights[members] / total[best]
    mean_xy = w @ p[:, :2]
    centred = p[:, :2] - mean_xy
    cov = np.zeros((3, 3))
    cov[:2, :2] = (centred * w[:, None]).T @ centred
    mc, ms = w @ np.cos(p[:, 2]), w @ np.sin(p[:, 2])
    cov[2, 2] = -2.0 * np.log(np.clip(np.hypot(mc, ms), 1e-12, 1.0))
    return PoseCluster(float(total[best]), np.array([mean_xy[0], mean_xy[1], np.arctan2(ms, mc)]), cov)
