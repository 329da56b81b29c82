"""KLD-sampling (Fox, 2003): how many particles are enough, given how many pose bins they occupy."""

from __future__ import annotations

import math

import numpy as np
from numba import njit


def kld_bound(k: np.ndarray | int, epsilon: float, z: float) -> np.ndarray:
    """Fox's bound n = (k-1)/(2 eps) (1 - 2/(9(k-1)) + sqrt(2/(9(k-1))) z)^3 for ``k`` occupied bins.

    ``z`` is used as given (nav2's ``pf_z``, 0.99 by default, enters the formula directly). For k <= 1
    the bound is undefined and returned as inf: a single bin says nothing about the spread.
    """
    k = np.asarray(k, dtype=float)
    with np.errstate(divide="ignore", invalid="ignore"):
        b = 2.0 / (9.0 * (k - 1.0))
        n = (k - 1.0) / (2.0 * epsilon) * (1.0 - b + np.sqrt(b) * z) ** 3
    return np.where(k > 1, np.ceil(n), np.inf)


def kld_limit(k: np.ndarray | int, epsilon: float, z: float, min_particles: int, max_particles: int) -> np.ndarray:
    """The bound clamped to [min_particles, max_particles]; ``max_particles`` while k <= 1, as in nav2. A floor
    above ``max_particles`` is ``max_particles``: a set smaller than the floor is kept whole."""
    bound = kld_bound(k, epsilon, z)
    floor = min(min_particles, max_particles)
    return np.where(np.isinf(bound), max_particles, np.clip(bound, floor, max_particles)).astype(int)


def bin_indices(poses: np.ndarray, xy_size: float, theta_size: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    """Integer (x, y, theta) bin of each pose (N, 3), and the number of theta bins; theta wraps around."""
    n_theta = int(np.ceil(2 * np.pi / theta_size))
    poses = np.ascontiguousarray(poses, dtype=float).reshape(-1, 3)
    ix, iy, it = _bins(poses, float(xy_size), float(theta_size), n_theta)
    return ix, iy, it, n_theta


@njit(cache=True, nogil=True)
def _bins(
    poses: np.ndarray, xy_size: float, theta_size: float, n_theta: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:  # pragma: no cover - compiled
    """floor(x / xy_size), floor(y / xy_size) and floor(mod(theta, 2 pi) / theta_size) mod n_theta, with NumPy's
    floating mod (fmod, moved into the divisor's sign; a zero takes the divisor's sign): the same integers as
    the NumPy expression it replaced (0.3 ms a call on 10 000 poses; tests/test_kld.py compares them)."""
    n = poses.shape[0]
    ix = np.empty(n, dtype=np.int64)
    iy = np.empty(n, dtype=np.int64)
    it = np.empty(n, dtype=np.int64)
    turn = 2 * np.pi
    for i in range(n):
        ix[i] = np.int64(math.floor(poses[i, 0] / xy_size))
        iy[i] = np.int64(math.floor(poses[i, 1] / xy_size))
        theta = poses[i, 2]
        wrapped = theta if -turn < theta < turn else np.fmod(theta, turn)  # fmod is exact: theta itself there
        if wrapped != 0.0:
            if wrapped < 0.0:
                wrapped += turn
        else:
            wrapped = 0.0
        it[i] = np.int64(math.floor(wrapped / theta_size)) % n_theta
    return ix, iy, it


def bin_keys(poses: np.ndarray, xy_size: float, theta_size: float) -> np.ndarray:
    """One int64 key per pose (N, 3) naming its (x, y, theta) bin."""
    ix, iy, it, _ = bin_indices(poses, xy_size, theta_size)
    return ((ix + (1 << 20)) << 32) | ((iy + (1 << 20)) << 8) | it


def kld_sample_count(keys: np.ndarray, epsilon: float, z: float, min_particles: int, max_particles: int) -> int:
    """How many of the draws ``keys`` (in draw order) nav2's adaptive loop keeps.

    It adds draws one at a time and stops once the count exceeds the limit for the bins occupied so far.
    """
    keys = np.asarray(keys)[:max_particles]
    if keys.size == 0:
        return 0
    _, first = np.unique(keys, return_index=True)
    new_bin = np.zeros(keys.size, dtype=int)
    new_bin[first] = 1
    bins_so_far = np.cumsum(new_bin)
    counts = np.arange(1, keys.size + 1)
    over = counts > kld_limit(bins_so_far, epsilon, z, min_particles, max_particles)
    return int(np.argmax(over) + 1) if over.any() else int(keys.size)
