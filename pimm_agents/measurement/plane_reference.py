"""A reference labelling of a real scan that has no labels, from plane fits, and the scores against it.

A real scan comes without wall / ceiling / floor labels. A reference anyone can rebuild: level the scan on its
floor (``perception/floor.py``), take RANSAC planes one after another (Open3D's ``segment_plane``, seeded) from
the scan thinned to one point per ``voxel_m``, and call

- **wall** every large upright plane (``|n_z| <= max_upright_nz``, spanning ``min_wall_width_m`` along the
  floor and ``min_wall_height_m`` up it),
- **floor** the lowest large level plane (``min_level_span_m`` across both ways) and **ceiling** the large
  level planes above the sensor within ``ceiling_band_m`` of the highest one (a ceiling of panels at a few
  heights),
- **clutter** everything else.

A plane here is one connected piece of a RANSAC plane's inliers (pieces joined within ``join_m``): desk tops
at one height across a room are as many pieces as desks, and none of them is large.

Each point of the scan takes its plane's class when it lies within ``distance_m`` of that plane and within
``reach_m`` of the plane's own thinned inliers (so a desk's front does not join a wall far behind it in the
same plane). Room corners are where two walls at least ``min_corner_angle_deg`` apart meet, both reaching
within ``corner_reach_m`` of the meeting line; a corner the segmenter reports counts as found within
``corner_match_m`` of one (in the floor plane).

The reference is a judgement of geometry, not of meaning: a large flat cabinet side counts as wall, a wall
broken into short stretches by shelves may not. It is the same judgement for every segmenter it scores.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from pimm_agents.perception.floor import Floor, FloorConfig, estimate_floor
from pimm_env.world.semantics import CLASS_NAMES, SemanticClass


@dataclass(frozen=True)
class ReferenceConfig:
    """Ours: the plane-fit rules above."""

    voxel_m: float = 0.05
    distance_m: float = 0.04
    iterations: int = 2000
    max_planes: int = 40
    min_inliers: int = 50  # thinned points, of a RANSAC plane and of each of its pieces
    max_upright_nz: float = 0.1
    min_level_nz: float = 0.97
    min_wall_width_m: float = 1.0
    min_wall_height_m: float = 1.0
    min_level_span_m: float = 1.5
    reach_m: float = 0.15
    join_m: float = 0.3
    ceiling_band_m: float = 0.3
    min_corner_angle_deg: float = 45.0
    corner_reach_m: float = 0.3
    corner_match_m: float = 0.2
    floor: FloorConfig = field(default_factory=FloorConfig)


@dataclass(frozen=True)
class PlaneFit:
    normal: np.ndarray  # unit, in the level frame
    offset: float  # n . p + offset = 0
    inliers: np.ndarray  # (K, 3) thinned inliers, level frame


@dataclass(frozen=True)
class Reference:
    labels: np.ndarray  # (N,) class per point of the scan
    corners: np.ndarray  # (C, 2) x, y of the room corners, level sensor frame
    floor: Floor
    walls: list[PlaneFit]


def level_points(points: np.ndarray, floor: Floor) -> np.ndarray:
    """The scan in a level frame at the sensor: the floor's normal along +z, the floor at z = -height."""
    return np.asarray(points, dtype=np.float64) @ floor.leveling.T


def plane_reference(points: np.ndarray, config: ReferenceConfig = ReferenceConfig(), seed: int = 0) -> Reference:
    """The reference labels and room corners of the scan ``points`` (N, 3, sensor frame)."""
    import open3d as o3d

    floor = estimate_floor(points, config.floor, seed)
    level = level_points(points, floor)
    thinned = np.asarray(
        o3d.geometry.PointCloud(o3d.utility.Vector3dVector(level)).voxel_down_sample(config.voxel_m).points
    )
    planes = _planes(thinned, config, seed)
    walls = [p for p in planes if abs(p.normal[2]) <= config.max_upright_nz and _wall_sized(p, config)]
    levels = [p for p in planes if abs(p.normal[2]) >= config.min_level_nz and _level_sized(p, config)]
    labels = np.full(len(level), int(SemanticClass.CLUTTER), dtype=np.int8)
    heights = np.array([float(np.median(p.inliers[:, 2])) for p in levels])
    if levels:
        lowest = int(np.argmin(heights))
        _claim(labels, level, levels[lowest], int(SemanticClass.FLOOR), config)
        for k in np.flatnonzero((heights > 0) & (heights >= heights.max() - config.ceiling_band_m)):
            if k != lowest:
                _claim(labels, level, levels[k], int(SemanticClass.CEILING), config)
    for wall in walls:
        _claim(labels, level, wall, int(SemanticClass.WALL), config)
    return Reference(labels=labels, corners=_corners(walls, config), floor=floor, walls=walls)


def _planes(points: np.ndarray, config: ReferenceConfig, seed: int) -> list[PlaneFit]:
    import open3d as o3d

    o3d.utility.random.seed(seed)
    found: list[PlaneFit] = []
    remaining = points
    for _ in range(config.max_planes):
        if len(remaining) < config.min_inliers:
            break
        cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(remaining))
        model, inliers = cloud.segment_plane(config.distance_m, 3, config.iterations)
        if len(inliers) < config.min_inliers:
            break
        normal = np.asarray(model[:3], dtype=float)
        scale = float(np.linalg.norm(normal))
        for piece in _pieces(remaining[inliers], config.join_m):
            if len(piece) >= config.min_inliers:
                found.append(PlaneFit(normal / scale, float(model[3]) / scale, piece))
        remaining = np.delete(remaining, inliers, axis=0)
    return found


def _pieces(points: np.ndarray, join_m: float) -> list[np.ndarray]:
    """The connected pieces of ``points``: points within ``join_m`` of each other are one piece."""
    from scipy.sparse.csgraph import connected_components
    from scipy.spatial import cKDTree

    pairs = cKDTree(points).query_pairs(join_m, output_type="ndarray")
    from scipy.sparse import coo_matrix

    graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(len(points), len(points)))
    count, piece = connected_components(graph, directed=False)
    return [points[piece == k] for k in range(count)]


def _spans(plane: PlaneFit) -> tuple[float, float]:
    """The inliers' extent along the plane's two in-plane axes (the second upright for an upright plane)."""
    n = plane.normal
    up = np.array([0.0, 0.0, 1.0])
    first = np.cross(up, n) if abs(n[2]) < 0.9 else np.array([1.0, 0.0, 0.0]) - n[0] * n
    first /= np.linalg.norm(first)
    second = np.cross(n, first)
    along, across = plane.inliers @ first, plane.inliers @ second
    return float(np.ptp(along)), float(np.ptp(across))


def _wall_sized(plane: PlaneFit, config: ReferenceConfig) -> bool:
    width, height = _spans(plane)
    return width >= config.min_wall_width_m and height >= config.min_wall_height_m


def _level_sized(plane: PlaneFit, config: ReferenceConfig) -> bool:
    return min(_spans(plane)) >= config.min_level_span_m


def _claim(labels: np.ndarray, points: np.ndarray, plane: PlaneFit, label: int, config: ReferenceConfig) -> None:
    from scipy.spatial import cKDTree

    near = np.abs(points @ plane.normal + plane.offset) <= config.distance_m
    index = np.flatnonzero(near)
    if len(index):
        distance, _ = cKDTree(plane.inliers).query(points[index], distance_upper_bound=config.reach_m)
        labels[index[np.isfinite(distance)]] = label


def _corners(walls: list[PlaneFit], config: ReferenceConfig) -> np.ndarray:
    """Where two upright walls meet, each reaching the meeting line in the floor plane."""
    corners = []
    for i, a in enumerate(walls):
        for b in walls[i + 1 :]:
            na, nb = a.normal[:2], b.normal[:2]
            sine = abs(na[0] * nb[1] - na[1] * nb[0]) / (np.linalg.norm(na) * np.linalg.norm(nb))
            if np.degrees(np.arcsin(min(1.0, sine))) < config.min_corner_angle_deg:
                continue
            corner = np.linalg.solve(np.array([na, nb]), -np.array([a.offset, b.offset]))
            reach = [np.min(np.linalg.norm(w.inliers[:, :2] - corner, axis=1)) for w in (a, b)]
            if max(reach) <= config.corner_reach_m:
                corners.append(corner)
    merged: list[list[np.ndarray]] = []  # pieces of one wall meet another in nearly one place: one corner
    for corner in corners:
        group = next((g for g in merged if np.linalg.norm(np.mean(g, axis=0) - corner) <= config.corner_reach_m), None)
        if group is None:
            merged.append([corner])
        else:
            group.append(corner)
    return np.array([np.mean(g, axis=0) for g in merged]).reshape(-1, 2)


def score_labels(predicted: np.ndarray, reference: np.ndarray) -> dict[str, object]:
    """Per-class IoU and their mean, and each class's share of the points in both labellings."""
    iou = {}
    for k, name in enumerate(CLASS_NAMES):
        union = np.sum((predicted == k) | (reference == k))
        iou[name] = float(np.sum((predicted == k) & (reference == k)) / union) if union else float("nan")
    valid = [v for v in iou.values() if np.isfinite(v)]
    shares = {
        which: {name: float(np.mean(labels == k)) for k, name in enumerate(CLASS_NAMES)}
        for which, labels in (("predicted", predicted), ("reference", reference))
    }
    return {"iou": iou, "mean_iou": float(np.mean(valid)) if valid else float("nan"), "shares": shares}


def corners_found(found: np.ndarray, reference: np.ndarray, within_m: float) -> dict[str, object]:
    """How many reference corners have a found corner within ``within_m``, and how many found ones match none."""
    found, reference = np.asarray(found).reshape(-1, 2), np.asarray(reference).reshape(-1, 2)
    if len(found) == 0 or len(reference) == 0:
        return {"reference": len(reference), "found": len(found), "matched": 0, "unmatched_found": len(found)}
    distance = np.linalg.norm(reference[:, None, :] - found[None, :, :], axis=2)
    matched = int(np.sum(distance.min(axis=1) <= within_m))
    unmatched = int(np.sum(distance.min(axis=0) > within_m))
    return {"reference": len(reference), "found": len(found), "matched": matched, "unmatched_found": unmatched}


def scored_against_reference(
    points: np.ndarray,
    labels: np.ndarray,
    found: np.ndarray,
    seed: int = 0,
    config: ReferenceConfig = ReferenceConfig(),
) -> tuple[Reference, dict[str, object]]:
    """The scan's plane-fit reference, and ``labels`` (one per point) and the corners ``found`` (x, y, level
    sensor frame) scored against it: IoU per class and their mean, class shares, room corners found within
    ``corner_match_m``."""
    reference = plane_reference(points, config, seed)
    scores = {
        **score_labels(labels, reference.labels),
        "corners": corners_found(found, reference.corners, config.corner_match_m),
        "reference_corners": np.round(reference.corners, 3).tolist(),
    }
    return reference, scores
