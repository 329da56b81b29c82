"""Plane extraction by repeated RANSAC: the dominant plane, its inliers removed, then the next (thesis 3.3.1).

Two RANSACs are offered. Open3D's ``segment_plane`` (the thesis's) draws planes of any orientation. Ours draws
only the orientation the class allows (walls: vertical planes through two points; ceilings: horizontal planes
through one), and its whole loop (hypotheses, scoring, the robust refit, taking the inliers out) is compiled
with numba: a scan's planes cost a tenth of what the same steps cost as NumPy calls (``evaluate.py bench``,
``corners_ms``; docs/design.md#measured-choices).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property, lru_cache

import numpy as np
from numba import njit

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


def robust_refit(points: np.ndarray, rounds: int = 3) -> tuple[np.ndarray, float, float, np.ndarray]:
    """Least-squares plane refitted a few times on the points within 3 robust sigmas of the last fit.

    RANSAC's band (0.2 m by default) also takes in the first 0.2 m of any wall meeting this one; trimming
    them keeps the corner where the two surfaces really meet. The normal is the eigenvector of the 3 x 3
    scatter matrix with the smallest eigenvalue, which is the RMS residual squared. Returns normal, offset,
    RMS and the kept points.
    """
    points = np.ascontiguousarray(points, dtype=float)
    normal, d, rms, kept = _robust_refit(points, rounds)
    return normal, float(d), float(rms), points[kept]


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
    plane through one point; "any": the plane through three points. Hypotheses are scored on the first
    ``score_points`` points (a random subset when the caller shuffled them), the best on all of them.
    """
    if orientation not in ORIENTATIONS:
        raise LocalizerError(f"orientation {orientation!r}: valid orientations are {ORIENTATIONS}")
    points = np.ascontiguousarray(points, dtype=float)
    if len(points) == 0:
        return np.zeros(0, dtype=np.int64)
    draws = rng.random((iterations, 3))
    xs, ys, zs = (np.ascontiguousarray(points[:, axis]) for axis in range(3))
    (nx, ny, nz, d), found = _best_plane(xs, ys, zs, draws, threshold, _ORIENTATION_CODE[orientation], score_points)
    if not found:
        return np.zeros(0, dtype=np.int64)
    return np.flatnonzero(np.abs(points @ np.array([nx, ny, nz]) + d) <= threshold)


def extract_planes(points: np.ndarray, params: PlaneParams, seed: int = 0, orientation: str = "any") -> list[Plane]:
    """Up to ``max_planes`` planes with at least ``min_inliers`` inliers each, largest first.

    Each RANSAC model is refitted to its inliers by trimmed least squares (:func:`robust_refit`). Both RANSACs
    are seeded, so that a scan always gives the same planes; ``orientation`` steers the constrained one only.
    """
    if orientation not in ORIENTATIONS:
        raise LocalizerError(f"orientation {orientation!r}: valid orientations are {ORIENTATIONS}")
    points = np.asarray(points, dtype=float)
    points = np.ascontiguousarray(points[finite_rows(points)])
    if params.method == "constrained":
        draws = _draws(seed, params.max_planes, params.iterations)
        normals, offsets, rms, owner = _extract(
            points, draws, params.distance_threshold, _ORIENTATION_CODE[orientation], params.score_points,
            params.min_inliers,
        )  # fmt: skip
        # each plane's inliers in scan order: one stable sort of the owners instead of a mask per plane
        small = owner.astype(np.int16) if len(rms) < 1 << 15 else owner  # a few owners: NumPy's radix sort
        order = np.argsort(small, kind="stable")
        ends = np.searchsorted(owner[order], np.arange(len(rms) + 1), side="left")
        return [
            Plane(normals[k], float(offsets[k]), points[order[ends[k] : ends[k + 1]]], float(rms[k]))
            for k in range(len(rms))
        ]
    return _open3d_planes(points, params, seed)


@lru_cache(maxsize=8)
def _draws(seed: int, planes: int, iterations: int) -> np.ndarray:
    """The constrained RANSAC's uniform draws for ``seed`` (the same every scan: made once, read-only)."""
    draws = np.random.default_rng(seed).random((planes, iterations, 3))
    draws.setflags(write=False)
    return draws


def _open3d_planes(points: np.ndarray, params: PlaneParams, seed: int) -> list[Plane]:
    """The thesis's loop: Open3D's ``segment_plane`` (any orientation), refitted as ours."""
    import open3d as o3d

    o3d.utility.random.seed(seed)
    planes: list[Plane] = []
    remaining = points
    while len(planes) < params.max_planes and len(remaining) >= params.min_inliers:
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


# ---- compiled RANSAC (the "constrained" method) ----

_ORIENTATION_CODE = {"any": 0, "vertical": 1, "horizontal": 2}


@njit(cache=True, nogil=True)
def _hypothesis(xs: np.ndarray, ys: np.ndarray, zs: np.ndarray, draw: np.ndarray, orientation: int) -> tuple:
    """The plane (unit normal, offset, made) through the points that ``draw`` (3 numbers in [0, 1)) picks;
    ``made`` is False when the picks make no plane (coincident points)."""
    count = xs.shape[0]
    i = min(int(draw[0] * count), count - 1)
    ax, ay, az = xs[i], ys[i], zs[i]
    nx, ny, nz = 0.0, 0.0, 1.0
    if orientation != 2:
        j = min(int(draw[1] * count), count - 1)
        u0, u1, u2 = xs[j] - ax, ys[j] - ay, zs[j] - az
        if orientation == 1:
            nx, ny, nz = -u1, u0, 0.0
        else:
            k = min(int(draw[2] * count), count - 1)
            v0, v1, v2 = xs[k] - ax, ys[k] - ay, zs[k] - az
            nx, ny, nz = u1 * v2 - u2 * v1, u2 * v0 - u0 * v2, u0 * v1 - u1 * v0
    norm = math.sqrt(nx * nx + ny * ny + nz * nz)
    if norm <= 1e-6:
        return 0.0, 0.0, 0.0, 0.0, False
    nx, ny, nz = nx / norm, ny / norm, nz / norm
    return nx, ny, nz, -(nx * ax + ny * ay + nz * az), True


@njit(cache=True, nogil=True)
def _best_plane(
    xs: np.ndarray,
    ys: np.ndarray,
    zs: np.ndarray,
    draws: np.ndarray,
    threshold: float,
    orientation: int,
    score_points: int,
) -> tuple:
    """Of one random plane per row of ``draws``, the one with the most of the first ``score_points`` points
    (coordinates ``xs``, ``ys``, ``zs``) within ``threshold`` (the first such on a tie); ``found`` False when
    no draw made a plane."""
    scored = min(score_points, xs.shape[0])
    best, best_plane, found = -1, (0.0, 0.0, 0.0, 0.0), False
    for h in range(draws.shape[0]):
        nx, ny, nz, d, made = _hypothesis(xs, ys, zs, draws[h], orientation)
        if not made:
            continue
        inside = 0
        for i in range(scored):
            inside += abs(nx * xs[i] + ny * ys[i] + nz * zs[i] + d) <= threshold
        if inside > best:
            best, best_plane, found = inside, (nx, ny, nz, d), True
    return best_plane, found


@njit(cache=True, nogil=True)
def _refit(points: np.ndarray) -> tuple:
    """Least-squares plane of ``points`` (K, 3): the scatter matrix's eigenvector of least eigenvalue."""
    n = points.shape[0]
    cx, cy, cz = 0.0, 0.0, 0.0
    for i in range(n):
        cx += points[i, 0]
        cy += points[i, 1]
        cz += points[i, 2]
    cx, cy, cz = cx / n, cy / n, cz / n
    sxx = sxy = sxz = syy = syz = szz = 0.0
    for i in range(n):
        x, y, z = points[i, 0] - cx, points[i, 1] - cy, points[i, 2] - cz
        sxx += x * x
        sxy += x * y
        sxz += x * z
        syy += y * y
        syz += y * z
        szz += z * z
    scatter = np.array([[sxx, sxy, sxz], [sxy, syy, syz], [sxz, syz, szz]]) / n
    values, vectors = np.linalg.eigh(scatter)
    normal = vectors[:, 0].copy()
    return normal, -(normal[0] * cx + normal[1] * cy + normal[2] * cz), math.sqrt(max(values[0], 0.0))


@njit(cache=True, nogil=True)
def _robust_refit(points: np.ndarray, rounds: int) -> tuple:
    """:func:`robust_refit`, compiled: the plane and a mask of the points it kept."""
    kept = np.ones(points.shape[0], dtype=np.bool_)
    normal, d, rms = _refit(points)
    for _ in range(rounds):
        residual = np.abs(points @ normal + d)
        inside = residual <= max(3.0 * 1.4826 * np.median(residual), 0.01)
        inside_count = inside.sum()
        if inside_count < 3 or inside_count == kept.sum():
            break
        kept = inside
        normal, d, rms = _refit(points[kept])
    return normal, d, rms, kept


@njit(cache=True, nogil=True)
def _extract(
    points: np.ndarray,
    draws: np.ndarray,
    threshold: float,
    orientation: int,
    score_points: int,
    min_inliers: int,
) -> tuple:
    """Up to ``draws.shape[0]`` planes, one RANSAC per row of ``draws`` on the points no earlier plane took,
    each refitted robustly. Returns normals (P, 3), offsets, RMS residuals and each point's plane (-1 none)."""
    n = points.shape[0]
    planes = draws.shape[0]
    normals, offsets, rms_of = np.zeros((planes, 3)), np.zeros(planes), np.zeros(planes)
    owner = np.full(n, -1, dtype=np.int64)
    alive = np.arange(n)  # the points no plane took yet, in their order (its first ones are the scored ones)
    xs, ys, zs = points[:, 0].copy(), points[:, 1].copy(), points[:, 2].copy()
    count, made = n, 0
    for k in range(planes):
        if count < min_inliers:
            break
        plane, found = _best_plane(xs[:count], ys[:count], zs[:count], draws[k], threshold, orientation, score_points)
        if not found:
            break
        nx, ny, nz, d = plane
        inliers = np.empty(count, dtype=np.int64)
        m = left = 0
        for i in range(count):  # the inliers leave the pool (kept by the refit or trimmed); the rest close up
            if abs(nx * xs[i] + ny * ys[i] + nz * zs[i] + d) <= threshold:
                inliers[m] = alive[i]
                m += 1
            else:
                alive[left], xs[left], ys[left], zs[left] = alive[i], xs[i], ys[i], zs[i]
                left += 1
        if m < min_inliers:
            break
        inliers = inliers[:m]
        normal, offset, rms, kept = _robust_refit(points[inliers], 3)
        normals[made], offsets[made], rms_of[made] = normal, offset, rms
        owner[inliers[kept]] = made
        made += 1
        count = left
    return normals[:made], offsets[:made], rms_of[:made], owner
