"""Per-point input features of the layout-free network, from any point set: no rings, columns or grid.

The scan comes levelled, in the sensor's frame, with the sensor's height above the floor (``floor.py`` or
the sensors file). It is thinned to one point per ``voxel_m`` cube (the mean of its returns), so a 16-ring
LiDAR, a 128-ring one and a non-repetitive pattern give point sets of about the same density; every return
later takes the class of its voxel. Each voxel point gets:

- its height above the floor (not over the sensor: the network is free of the mount height), its horizontal
  range, its height as a share of the scan's top;
- its surface from its ``neighbours`` nearest voxel points: |n_z| of the normal, |n . radial| (facing the
  sensor or seen edge-on), and the roughness (the RMS distance from the fitted plane, capped);
- what lies in its azimuth sector (``sectors`` sectors around the sensor, which any scan that sweeps around has,
  whatever its pattern): how far under the sector's top it is, its range over the sector's farthest and how
  far short of it, and the vertical extent of the surface at its range in that sector (``range_bin_m`` bins;
  the neighbouring bins count too), above and below it: a wall runs from floor to ceiling at one range, a
  desk front stops at 0.75 m;
- the same sector profile to either side (``context_sectors``): how far the farthest return and the top of the
  sectors ``k`` to the left and right are from its own range and height: whether the surface goes on.

Every feature is invariant to the sensor's heading, as the grid network's are.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pimm_env.errors import ObservationError

CLOUD_FEATURES: tuple[str, ...] = (
    "height",  # above the floor (m)
    "horizontal_range",
    "height_share",  # height / the scan's top
    "normal_z",
    "normal_radial",
    "roughness",
    "below_sector_top",
    "sector_depth",  # horizontal range / the sector's farthest
    "before_sector_end",  # m short of the sector's farthest
    "surface_span",  # vertical extent of returns at this range in this sector (m)
    "surface_above",
    "surface_below",
    "left_2_range", "right_2_range", "left_6_range", "right_6_range", "left_15_range", "right_15_range",
    "left_2_top", "right_2_top", "left_6_top", "right_6_top", "left_15_top", "right_15_top",
)  # fmt: skip
#: Rough scale of each feature, so that the first layer sees numbers near 1.
CLOUD_FEATURE_SCALE: tuple[float, ...] = (
    3.0, 10.0, 1.0, 1.0, 1.0, 0.05, 3.0, 1.0, 5.0, 3.0, 3.0, 3.0, *([5.0] * 6), *([3.0] * 6)
)  # fmt: skip
CLOUD_NUM_FEATURES = len(CLOUD_FEATURES)


@dataclass(frozen=True)
class CloudFeatureConfig:
    """Ours, chosen so that the thinned scan of a room has a few thousand points and a wall's sector profile
    holds for any LiDAR from 16 rings up."""

    voxel_m: float = 0.08
    neighbours: int = 8
    sectors: int = 180  # 2 deg each
    range_bin_m: float = 0.15
    context_sectors: tuple[int, ...] = (2, 6, 15)
    roughness_cap: float = 0.2
    max_range_m: float = 40.0  # sector profiles are kept to this range


@dataclass(frozen=True)
class ThinnedScan:
    points: np.ndarray  # (M, 3) voxel means, level sensor frame
    voxel_of: np.ndarray  # (N,) each return's voxel
    chosen: np.ndarray  # (K,) the voxels the network looks at
    features: np.ndarray  # (K, CLOUD_NUM_FEATURES) float32, of the chosen voxels


def spread_sample(count: int, wanted: int, offset: int = 0) -> np.ndarray:
    """``wanted`` of ``count`` voxels, evenly strided through them (voxels are in key order, so this spreads over
    space); with fewer voxels than ``wanted`` every one, repeated to fill (which changes neither the max-pooled
    global feature nor any point's class)."""
    if count <= wanted:
        return np.resize(np.arange(count), wanted)
    stride = count / wanted
    return np.minimum((offset % max(1, int(stride)) + stride * np.arange(wanted)).astype(np.int64), count - 1)


def voxelize(points: np.ndarray, voxel_m: float) -> tuple[np.ndarray, np.ndarray]:
    """The mean of the returns in each occupied ``voxel_m`` cube, and each return's cube."""
    keys = np.floor(points / voxel_m).astype(np.int64)
    keys -= keys.min(axis=0)
    span = keys.max(axis=0) + 1
    flat = (keys[:, 0] * span[1] + keys[:, 1]) * span[2] + keys[:, 2]
    _, inverse = np.unique(flat, return_inverse=True)
    count = np.bincount(inverse).astype(np.float64)
    means = np.column_stack([np.bincount(inverse, weights=points[:, k]) / count for k in range(3)])
    return means, inverse.reshape(-1)


def _surface(points: np.ndarray, at: np.ndarray, neighbours: int) -> tuple[np.ndarray, np.ndarray]:
    """Unit normals and RMS plane distances at ``points[at]`` from their ``neighbours`` nearest points."""
    from scipy.spatial import cKDTree

    k = min(neighbours, len(points))
    _, index = cKDTree(points, balanced_tree=False, compact_nodes=False).query(points[at], k=k)
    near = points[index.reshape(len(at), k)]
    centred = near - near.mean(axis=1, keepdims=True)
    x, y, z = centred[..., 0], centred[..., 1], centred[..., 2]
    moments = [np.einsum("mk,mk->m", u, v) / k for u, v in ((x, x), (y, y), (z, z), (x, y), (y, z), (x, z))]
    smallest, normal = smallest_eigen(*moments)
    return normal, np.sqrt(smallest)


def smallest_eigen(
    xx: np.ndarray, yy: np.ndarray, zz: np.ndarray, xy: np.ndarray, yz: np.ndarray, xz: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The smallest eigenvalue and its unit eigenvector of symmetric 3 x 3 matrices given by their six entries
    (arrays of one length), in closed form: the trigonometric root of the characteristic cubic, then the
    largest cross product of two rows of (C - lambda I). Ten times faster than ``np.linalg.eigh`` on 2 048."""
    q = (xx + yy + zz) / 3
    a, b, c = xx - q, yy - q, zz - q
    p = np.sqrt(np.maximum((a * a + b * b + c * c + 2 * (xy * xy + yz * yz + xz * xz)) / 6, 1e-30))
    det = a * (b * c - yz * yz) - xy * (xy * c - yz * xz) + xz * (xy * yz - b * xz)
    lam = q + 2 * p * np.cos(np.arccos(np.clip(det / (2 * p**3), -1, 1)) / 3 + 2 * np.pi / 3)
    a, b, c = xx - lam, yy - lam, zz - lam
    c01 = np.stack([xy * yz - xz * b, xz * xy - a * yz, a * b - xy * xy])
    c02 = np.stack([xy * c - xz * yz, xz * xz - a * c, a * yz - xy * xz])
    c12 = np.stack([b * c - yz * yz, yz * xz - xy * c, xy * yz - b * xz])
    n01, n02, n12 = (np.einsum("ij,ij->j", v, v) for v in (c01, c02, c12))
    vector, size = np.where(n01 >= n02, c01, c02), np.maximum(n01, n02)
    vector, size = np.where(n12 > size, c12, vector), np.maximum(size, n12)
    return np.maximum(lam, 0.0), (vector / np.sqrt(np.maximum(size, 1e-60))).T


def cloud_features(
    level: np.ndarray,
    sensor_height: float,
    wanted: int,
    config: CloudFeatureConfig = CloudFeatureConfig(),
    offset: int = 0,
) -> ThinnedScan:
    """The thinned scan and the features of ``wanted`` of its voxels (:func:`spread_sample` with ``offset``);
    ``level`` (N, 3) are the returns in the level sensor frame."""
    level = np.asarray(level, dtype=np.float64)
    if level.ndim != 2 or level.shape[1] != 3 or len(level) == 0 or not np.isfinite(level).all():
        raise ObservationError(f"cloud_features takes a non-empty (N, 3) array of finite returns, got {level.shape}")
    points, voxel_of = voxelize(level, config.voxel_m)
    chosen = spread_sample(len(points), wanted, offset)
    all_height = points[:, 2] + sensor_height
    all_horizontal = np.hypot(points[:, 0], points[:, 1])
    s = config.sectors
    all_sector = (np.floor((np.arctan2(points[:, 1], points[:, 0]) + np.pi) / (2 * np.pi) * s).astype(np.int64)) % s
    far = np.zeros(s)
    np.maximum.at(far, all_sector, all_horizontal)
    sector_top = np.full(s, -np.inf)
    np.maximum.at(sector_top, all_sector, all_height)
    sector_top = np.where(np.isfinite(sector_top), sector_top, 0.0)
    bins = int(np.ceil(config.max_range_m / config.range_bin_m)) + 2
    all_cell = all_sector * bins + np.clip(
        np.floor(all_horizontal / config.range_bin_m).astype(np.int64) + 1, 1, bins - 2
    )
    low = np.full(s * bins, np.inf)
    high = np.full(s * bins, -np.inf)
    np.minimum.at(low, all_cell, all_height)
    np.maximum.at(high, all_cell, all_height)
    top = max(
        float(np.partition(all_height, int(0.99 * (len(all_height) - 1)))[int(0.99 * (len(all_height) - 1))]), 0.5
    )

    normal, rough = _surface(points, chosen, config.neighbours)
    x, y = points[chosen, 0], points[chosen, 1]
    height, horizontal = all_height[chosen], all_horizontal[chosen]
    sector, cell = all_sector[chosen], all_cell[chosen]
    inv = 1.0 / np.maximum(horizontal, 1e-6)
    radial = np.abs(normal[:, 0] * x * inv + normal[:, 1] * y * inv)
    lo = np.minimum(np.minimum(low[cell - 1], low[cell]), low[cell + 1])
    hi = np.maximum(np.maximum(high[cell - 1], high[cell]), high[cell + 1])

    context_range, context_top = [], []
    for k in config.context_sectors:
        for side in (-1, 1):
            other = (sector + side * k) % s
            context_range.append(far[other] - horizontal)
            context_top.append(sector_top[other] - height)
    features = np.column_stack(
        [
            height,
            horizontal,
            height / top,
            np.abs(normal[:, 2]),
            radial,
            np.minimum(rough, config.roughness_cap),
            sector_top[sector] - height,
            horizontal / np.maximum(far[sector], 1e-6),
            far[sector] - horizontal,
            hi - lo,
            hi - height,
            height - lo,
            *context_range,
            *context_top,
        ]
    )
    return ThinnedScan(points=points, voxel_of=voxel_of, chosen=chosen, features=features.astype(np.float32))
