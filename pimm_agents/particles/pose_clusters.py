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


def cluster_statistics(
    poses: np.ndarray, weights: np.ndarray, labels: np.ndarray, limit: int | None = None
) -> list[PoseCluster]:
    """Weight, weighted mean (circular in theta) and covariance of every cluster (the ``limit`` heaviest),
    heaviest first.

    x and y get their weighted covariance; theta the circular variance -2 ln R, R the mean resultant length,
    and no correlation with x and y (nav2 reports the same). A cluster of no weight gets its particles'
    unweighted statistics.
    """
    count = int(labels.max()) + 1 if len(labels) else 0
    total = np.bincount(labels, weights, minlength=count)
    members = np.bincount(labels, minlength=count).astype(float)
    # Within-cluster weights: a weightless cluster weighs its particles alike.
    share = np.where(total[labels] > 0, weights / np.where(total[labels] > 0, total[labels], 1.0), 0.0)
    share = np.where(total[labels] > 0, share, 1.0 / members[labels])
    sums = [np.bincount(labels, share * column, minlength=count) for column in (poses[:, 0], poses[:, 1])]
    mx, my = sums
    mc = np.bincount(labels, share * np.cos(poses[:, 2]), minlength=count)
    ms = np.bincount(labels, share * np.sin(poses[:, 2]), minlength=count)
    dx, dy = poses[:, 0] - mx[labels], poses[:, 1] - my[labels]
    cxx = np.bincount(labels, share * dx * dx, minlength=count)
    cyy = np.bincount(labels, share * dy * dy, minlength=count)
    cxy = np.bincount(labels, share * dx * dy, minlength=count)
    ctt = -2.0 * np.log(np.clip(np.hypot(mc, ms), 1e-12, 1.0))
    clusters = []
    for k in np.argsort(-total, kind="stable")[:limit]:
        cov = np.array([[cxx[k], cxy[k], 0.0], [cxy[k], cyy[k], 0.0], [0.0, 0.0, ctt[k]]])
        mean = np.array([mx[k], my[k], np.arctan2(ms[k], mc[k])])
        clusters.append(PoseCluster(float(total[k]), mean, cov))
    return clusters


def heaviest_cluster(poses: np.ndarray, weights: np.ndarray, labels: np.ndarray) -> PoseCluster:
    """The cluster with the most weight (``cluster_statistics``' first)."""
    return cluster_statistics(poses, weights, labels, limit=1)[0]
