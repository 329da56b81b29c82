"""Corners where two walls meet a ceiling, from a segmented 3D scan (thesis 3.3).

Wall and ceiling points are split into planes by RANSAC; every well-conditioned pair of vertical wall planes
with one horizontal ceiling plane is intersected; an intersection is kept only near the inliers of all three.
Each corner's orientation is the floor projection of the bisector towards the two walls' inlier centroids.

Covariances come from the plane fits instead of hand tuning: a plane's offset along its normal is uncertain
by its RMS residual over sqrt(n), plus its tilt (RMS / (spread * sqrt(n))) times the distance from its centroid
to the corner; these three offset variances map to the corner through the inverse of the 3 x 3 system.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from itertools import combinations

import numpy as np
from numba import njit

from pimm_agents.corners.planes import Plane, PlaneParams, extract_planes
from pimm_agents.perception.point_arrays import finite_rows
from pimm_env.errors import LocalizerError
from pimm_env.world.semantics import SemanticClass

#: The detector's fixed choices (thesis section 3.3.4, or measured on 150 fresh scans, seeds 1-3; each in
#: docs/design.md#corners): RANSAC draws upright wall planes and level ceiling planes only, each hypothesis scored
#: on SCORE_POINTS points (``planes.constrained_ransac``), at most MAX_PLANES planes of RANSAC_ITERATIONS draws
MAX_PLANES, RANSAC_ITERATIONS, SCORE_POINTS = 20, 100, 600
VERTICAL_MAX_NZ = 0.1  # walls: |n_z| below this (thesis)
HORIZONTAL_MIN_NZ = 0.9  # ceilings: |n_z| above this (thesis)
MIN_PLANE_ANGLE = np.pi / 4  # every pair of the three normals at least this far from parallel (thesis)
MIN_FACE = 0.3  # m, the corner map's rule: each wall runs on at least this far from the corner...
MIN_FACE_POINTS = 5  # ... with this many inliers on that stretch
FACE_BAND = 3.0  # m: and within this height of the corner
THROUGH_POINTS = 7  # a wall with this many inliers past the corner as well runs through it...
THROUGH_BAND = 2.0  # m: ... counting only inliers within this height of the corner
#: m: each wall has a wall return this close to the corner's vertical edge (in the floor plane), counting the
#: returns within WALL_GAP_BAND of its plane (or 3 RMS of its fit): drops the phantoms of doorway gaps
MAX_WALL_GAP, WALL_GAP_BAND = 0.5, 0.1
MAX_POINTS_PER_CLASS = 2500  # random subsample of each class, for speed
MIN_POSITION_STD, MIN_ORIENTATION_STD = 0.02, float(np.radians(1.0))  # floors on the derived uncertainty


@dataclass(frozen=True)
class CornerDetectorConfig:
    """Thesis section 3.3.4's values, the inlier minimum scaled to the subsampled classes (measured)."""

    distance_threshold: float = 0.2  # thesis: RANSAC's inlier distance (m)
    min_inliers: int = 20  # measured: the thesis's 150 for 10 000-point clouds, scaled (docs/design.md#corners)
    max_corner_distance: float = 2.0  # thesis: from the corner to the nearest inlier of each plane (m)
    merge_distance: float = 0.5  # thesis: corners closer than this are one (m)

    def __post_init__(self) -> None:
        for name in ("distance_threshold", "max_corner_distance", "merge_distance"):
            if not getattr(self, name) > 0:
                raise LocalizerError(f"corners.{name} must be positive, got {getattr(self, name)}")
        if self.min_inliers < 3:
            raise LocalizerError(f"corners.min_inliers must be at least 3, got {self.min_inliers}")

    @property
    def planes(self) -> PlaneParams:
        """What RANSAC is run with."""
        return PlaneParams(
            MAX_PLANES, self.distance_threshold, self.min_inliers, RANSAC_ITERATIONS, "constrained", SCORE_POINTS
        )


@dataclass(frozen=True)
class Feature:
    """One corner in the robot frame, as the thesis's Feature.msg: type, confidence, pose and uncertainty."""

    x: float
    y: float
    theta: float
    position_covariance: np.ndarray  # 2 x 2
    orientation_variance: float
    confidence: float  # 1 when the vertex itself was seen, falling to 0 at max_corner_distance
    type: str = "corner"


@dataclass(frozen=True)
class FeatureList:
    stamp: float  # sim time of the scan the corners came from
    features: list[Feature]

    def __len__(self) -> int:
        return len(self.features)


def detect_corners(
    points: np.ndarray,
    labels: np.ndarray,
    stamp: float = 0.0,
    config: CornerDetectorConfig | None = None,
    seed: int = 0,
) -> FeatureList:
    """Corners in the frame of ``points`` (N, 3), given a class per point; NaN points are ignored."""
    config = config or CornerDetectorConfig()
    points = np.asarray(points).reshape(-1, 3)
    labels = np.asarray(labels).reshape(-1)
    if len(points) != len(labels):
        raise LocalizerError(f"{len(points)} points but {len(labels)} labels")
    rng = np.random.default_rng(seed)
    wall_points = _points_of(points, labels, SemanticClass.WALL)
    walls = _planes_of(wall_points, config, rng, seed, "vertical")
    walls = [p for p in walls if abs(p.normal[2]) < VERTICAL_MAX_NZ]
    if len(walls) < 2:
        return FeatureList(stamp, [])
    ceilings = _planes_of(_points_of(points, labels, SemanticClass.CEILING), config, rng, seed + 1, "horizontal")
    ceilings = [p for p in ceilings if abs(p.normal[2]) > HORIZONTAL_MIN_NZ]
    candidates = [
        feature
        for a, b, ceiling, corner in _intersections(walls, ceilings, config)
        if (feature := _corner(a, b, ceiling, corner, wall_points, config)) is not None
    ]
    return FeatureList(stamp, _merge(candidates, config.merge_distance))


def _points_of(points: np.ndarray, labels: np.ndarray, semantic: SemanticClass) -> np.ndarray:
    """The finite points of one class, as float64."""
    chosen = np.asarray(points[labels == semantic], dtype=float)
    return chosen[finite_rows(chosen)]


def _planes_of(
    points: np.ndarray, config: CornerDetectorConfig, rng: np.random.Generator, seed: int, orientation: str
) -> list[Plane]:
    if MAX_POINTS_PER_CLASS and len(points) > MAX_POINTS_PER_CLASS:
        points = points[rng.choice(len(points), MAX_POINTS_PER_CLASS, replace=False)]
    return extract_planes(points, config.planes, seed, orientation)


def _intersections(
    walls: list[Plane], ceilings: list[Plane], config: CornerDetectorConfig
) -> list[tuple[Plane, Plane, Plane, np.ndarray]]:
    """Each pair of walls with each ceiling whose normals are all at least ``min_plane_angle`` apart, with the
    point where the three planes meet, kept when that point lies within ``max_corner_distance`` of all three
    planes' inlier boxes (a cheap lower bound on the distance to their inliers). One batched solve."""
    if not ceilings:
        return []
    triples = [(a, b, c) for c in ceilings for a, b in combinations(walls, 2)]
    normals = np.array([[a.normal, b.normal, c.normal] for a, b, c in triples])
    max_cos = np.cos(MIN_PLANE_ANGLE) + 1e-12
    cosines = np.abs(np.einsum("kij,klj->kil", normals, normals))[:, [0, 0, 1], [1, 2, 2]]
    apart = np.all(cosines <= max_cos, axis=1)
    if not apart.any():
        return []
    offsets = np.array([[a.d, b.d, c.d] for a, b, c in triples])
    corners = np.linalg.solve(normals[apart], -offsets[apart][..., None])[..., 0]
    kept = [triple for triple, ok in zip(triples, apart, strict=True) if ok]
    lower = np.array([[p.bounds[0] for p in triple] for triple in kept])
    upper = np.array([[p.bounds[1] for p in triple] for triple in kept])
    outside = np.maximum(np.maximum(lower - corners[:, None], corners[:, None] - upper), 0.0)
    near = np.all(np.linalg.norm(outside, axis=2) <= config.max_corner_distance, axis=1)
    return [(*triple, corner) for triple, corner, ok in zip(kept, corners, near, strict=True) if ok]


def _corner(
    a: Plane, b: Plane, ceiling: Plane, corner: np.ndarray, wall_points: np.ndarray, config: CornerDetectorConfig
) -> Feature | None:
    """The corner where the three planes meet at ``corner``, or None where a rule rejects it; ``wall_points``
    are every wall return of the scan (the planes were fitted to a subsample)."""
    reach = _nearest_distance(ceiling.inliers, corner)
    if reach > config.max_corner_distance:
        return None
    for wall in (a, b):
        distance, ends = _wall_checks(wall, corner, config)
        if distance > config.max_corner_distance or not ends:
            return None
        reach = max(reach, distance)
    if MAX_WALL_GAP > 0:
        allowed = MAX_WALL_GAP
        for wall in (a, b):
            band = max(WALL_GAP_BAND, 3 * wall.rms)
            if _floor_gap(wall_points, np.array([*wall.normal, wall.d]), band, corner) > allowed:
                return None
    towards = [(p.centroid - corner)[:2] for p in (a, b)]
    bisector = sum(v / max(np.linalg.norm(v), 1e-9) for v in towards)
    if np.linalg.norm(bisector) < 1e-6:
        return None
    normals = np.stack([a.normal, b.normal, ceiling.normal])
    position_cov, orientation_var = _uncertainty(normals, (a, b, ceiling), corner, config)
    return Feature(
        float(corner[0]),
        float(corner[1]),
        float(np.arctan2(bisector[1], bisector[0])),
        position_cov,
        orientation_var,
        float(max(0.0, 1.0 - reach / config.max_corner_distance)),
    )


def _ends_at(wall: Plane, corner: np.ndarray, config: CornerDetectorConfig) -> bool:
    """Whether the wall ends at the corner: its face runs on from it, on one side only.

    Along the wall, inliers between ``min_face`` and ``max_corner_distance`` from the corner are counted on
    each side. The corner map keeps a corner only if both faces run straight for ``min_face``, so a sliver of
    wall (a pier, a door jamb) meeting another is no corner: one side needs ``min_face_points`` within
    ``face_band`` of the corner's height (a partition far below a high ceiling is no face of that ceiling's
    corner). A wall with ``through_points`` on both sides, within ``through_band`` of the corner's height,
    passes the corner by: its intersection with a wall that stops short of it (in another room, behind a
    doorway) or with two parallel faces that RANSAC's band merged into one plane is a phantom. The height
    band keeps real corners where a wall runs on past the corner only lower down, under a step in the ceiling.
    """
    return _wall_checks(wall, corner, config)[1]


def _wall_checks(wall: Plane, corner: np.ndarray, config: CornerDetectorConfig) -> tuple[float, bool]:
    """The distance from the corner to the wall's nearest inlier, and whether the wall ends at the corner
    (:func:`_ends_at`), in one pass over its inliers."""
    return _compiled_wall_checks(
        wall.inliers, wall.normal, np.asarray(corner, dtype=float), config.max_corner_distance, MIN_FACE,
        MIN_FACE_POINTS, FACE_BAND, THROUGH_POINTS, THROUGH_BAND,
    )  # fmt: skip


@njit(cache=True, nogil=True)
def _compiled_wall_checks(
    inliers: np.ndarray,
    normal: np.ndarray,
    corner: np.ndarray,
    max_corner_distance: float,
    min_face: float,
    min_face_points: int,
    face_band: float,
    through_points: int,
    through_band: float,
) -> tuple[float, bool]:
    ax, ay = -normal[1], normal[0]
    norm = max(math.sqrt(ax * ax + ay * ay), 1e-9)
    ax, ay = ax / norm, ay / norm
    nearest = np.inf
    face_ahead = face_behind = near_ahead = near_behind = 0
    for i in range(inliers.shape[0]):
        dx, dy, dz = inliers[i, 0] - corner[0], inliers[i, 1] - corner[1], inliers[i, 2] - corner[2]
        nearest = min(nearest, dx * dx + dy * dy + dz * dz)
        t = dx * ax + dy * ay
        if not min_face <= abs(t) <= max_corner_distance:
            continue
        height = abs(dz)
        if height <= face_band:
            face_ahead += t > 0
            face_behind += t < 0
        if height <= through_band:
            near_ahead += t > 0
            near_behind += t < 0
    if min_face > 0 and max(face_ahead, face_behind) < min_face_points:
        return math.sqrt(nearest), False
    return math.sqrt(nearest), through_points <= 0 or min(near_ahead, near_behind) < through_points


@njit(cache=True, nogil=True)
def _nearest_distance(points: np.ndarray, corner: np.ndarray) -> float:
    """Distance from ``corner`` to the nearest of ``points`` (K, 3)."""
    best = np.inf
    for i in range(points.shape[0]):
        dx, dy, dz = points[i, 0] - corner[0], points[i, 1] - corner[1], points[i, 2] - corner[2]
        best = min(best, dx * dx + dy * dy + dz * dz)
    return math.sqrt(best)


@njit(cache=True, nogil=True)
def _floor_gap(points: np.ndarray, plane: np.ndarray, band: float, corner: np.ndarray) -> float:
    """Distance in the floor plane from the corner's vertical edge to the nearest of ``points`` within ``band``
    of ``plane`` (normal and offset, 4 numbers)."""
    best = np.inf
    for i in range(points.shape[0]):
        x, y, z = points[i, 0], points[i, 1], points[i, 2]
        if abs(plane[0] * x + plane[1] * y + plane[2] * z + plane[3]) <= band:
            best = min(best, (x - corner[0]) ** 2 + (y - corner[1]) ** 2)
    return math.sqrt(best)


def _uncertainty(
    normals: np.ndarray, planes: tuple[Plane, Plane, Plane], corner: np.ndarray, config: CornerDetectorConfig
) -> tuple[np.ndarray, float]:
    offset_var, tilt_var = [], []
    for plane in planes:
        n = len(plane.inliers)
        tilt = plane.rms**2 / (n * plane.spread**2)
        lever = float(np.linalg.norm(corner - plane.centroid))
        offset_var.append(plane.rms**2 / n + tilt * lever**2)
        tilt_var.append(tilt)
    inverse = np.linalg.inv(normals)
    cov = inverse @ np.diag(offset_var) @ inverse.T
    position = cov[:2, :2] + np.eye(2) * MIN_POSITION_STD**2
    orientation = (tilt_var[0] + tilt_var[1]) / 4 + MIN_ORIENTATION_STD**2
    return position, float(orientation)


def _merge(features: list[Feature], distance: float) -> list[Feature]:
    """Greedy: the most confident corner absorbs the others within ``distance``; positions are averaged."""
    merged: list[Feature] = []
    remaining = sorted(features, key=lambda f: -f.confidence)
    while remaining:
        head = remaining[0]
        near = [f for f in remaining if np.hypot(f.x - head.x, f.y - head.y) < distance]
        remaining = [f for f in remaining if np.hypot(f.x - head.x, f.y - head.y) >= distance]
        merged.append(
            Feature(
                float(np.mean([f.x for f in near])),
                float(np.mean([f.y for f in near])),
                head.theta,
                head.position_covariance,
                head.orientation_variance,
                head.confidence,
            )
        )
    return merged
