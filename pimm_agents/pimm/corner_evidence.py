"""The filter's corner likelihood (thesis eq. 3.15) for every particle and feature, compiled.

Each feature (robot frame) is placed in the map from each particle, its nearest map corner read from the
lookup grid's cell (``corners/lookup.py``: the cell index as ``NearestCornerGrid.cells`` computes it, heading
bins included), and the exponent of the cubed likelihood, -3 (d^2 / 2 sigma_pos^2 + dtheta^2 / 2 sigma_theta^2),
written out. The same float32 operations, in the same order, as the NumPy expression it replaced, so the
exponents are equal to the bit (the test compares them); NumPy then takes their ``exp`` (so that the
exponential is NumPy's own) and sums them. In NumPy the 20-odd whole-array operations on (features x
particles) arrays cost more in call overhead than in arithmetic once a converged set is 1 500 particles.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from pimm_agents.corners.lookup import NearestCornerGrid

TWO_PI = np.float32(2 * np.pi)
INV_TWO_PI = np.float32(1 / (2 * np.pi))


def corner_likelihoods(lookup: NearestCornerGrid, features: np.ndarray, poses: np.ndarray) -> np.ndarray:
    """Eq. 3.15 summed as cubes over the features (F, 5: x, y, theta, sigma_pos, sigma_theta; robot frame) for
    each of ``poses`` (N, 3): L_total (N,). The filter's hot loop (10 000 particles x 5 features per update):
    float32, the exponents compiled, the nearest corner read straight from the lookup grid's cells."""
    f = np.asarray(features, dtype=np.float32).reshape(-1, 5)
    x, y, theta = np.asarray(poses).T.astype(np.float32)
    # L^3 = exp(-3 (d^2 / 2 sigma_pos^2 + da^2 / 2 sigma_theta^2))
    exponent = corner_exponents(lookup, f, x, y, theta)
    # exp(-60) ~ 1e-26 is nothing; lower, float32 goes subnormal (slow)
    np.maximum(exponent, np.float32(-60.0), out=exponent)
    np.exp(exponent, out=exponent)
    return exponent.sum(axis=0, dtype=np.float64)


def corner_exponents(
    lookup: NearestCornerGrid, features: np.ndarray, x: np.ndarray, y: np.ndarray, theta: np.ndarray
) -> np.ndarray:
    """(F, N) float32: per feature (F, 5 float32: x, y, theta, sigma_pos, sigma_theta) and particle (x, y,
    theta: N float32 each), the exponent of its cubed corner likelihood."""
    return _exponents(
        features,
        x,
        y,
        theta,
        np.cos(theta),
        np.sin(theta),
        np.float32(lookup.origin[0]),
        np.float32(lookup.origin[1]),
        np.float32(1.0 / lookup.resolution),
        lookup.shape[0] * lookup.shape[1] - 1,
        np.float32(lookup.shape[1]),
        lookup.bins,
        np.float32(lookup.bins / (2 * np.pi)),
        lookup.cell_xy,
        lookup.cell_theta,
    )


@njit(cache=True, nogil=True)
def _exponents(
    features: np.ndarray,
    x: np.ndarray,
    y: np.ndarray,
    theta: np.ndarray,
    cos: np.ndarray,
    sin: np.ndarray,
    origin_x: np.float32,
    origin_y: np.float32,
    inv_resolution: np.float32,
    last_cell: int,
    columns: np.float32,
    bins: int,
    bins_per_radian: np.float32,
    cell_xy: np.ndarray,
    cell_theta: np.ndarray,
) -> np.ndarray:
    f_count, n = features.shape[0], x.shape[0]
    out = np.empty((f_count, n), dtype=np.float32)
    zero, top = np.float32(0.0), np.float32(last_cell)
    power_of_two = bins & (bins - 1) == 0
    for i in range(f_count):
        fx, fy, fa = features[i, 0], features[i, 1], features[i, 2]
        k_pos = np.float32(-1.5) / (features[i, 3] * features[i, 3])
        k_theta = np.float32(-1.5) / (features[i, 4] * features[i, 4])
        for j in range(n):
            mx = fx * cos[j]
            mx = mx - fy * sin[j]
            mx = mx + x[j]
            my = fy * cos[j]
            my = my + fx * sin[j]
            my = my + y[j]
            da = theta[j] + fa
            flat = np.floor((my - origin_y) * inv_resolution)
            flat = flat * columns
            flat = flat + np.floor((mx - origin_x) * inv_resolution)
            flat = min(max(flat, zero), top)
            cell = np.int32(flat)
            if bins > 1:
                heading = np.int32(np.floor(da * bins_per_radian))
                heading = heading & (bins - 1) if power_of_two else heading % bins
                cell = cell * bins + heading
            corner = cell_xy[cell]
            mx = mx - corner.real
            my = my - corner.imag
            da = da - cell_theta[cell]
            da = da - TWO_PI * np.rint(da * INV_TWO_PI)
            mx = mx * mx
            my = my * my
            mx = mx + my
            mx = mx * k_pos
            da = da * da
            da = da * k_theta
            out[i, j] = mx + da
    return out
