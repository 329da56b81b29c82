"""Where in the map could this scan have been taken? FPFH matches between scan and map, and a RANSAC over
pairs of them for a ground robot's pose (x, y, yaw): two matches fix it, heights must agree.

Open3D's own RANSAC searches all six degrees of freedom and draws from Open3D's global random state; a robot
on a floor has four (z, roll and pitch are known), so a pair of matches is enough, and our draws come from
the localizer's seeded generator.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pimm_env.geometry import wrap_angle


@dataclass(frozen=True)
class SearchConfig:
    """Ours (hdl_global_localization's approach, our values)."""

    iterations: int = 4000  # pairs of matches drawn
    inlier_distance_m: float = 0.5  # a match agrees with a pose if the pose puts it this close (x, y)
    max_height_gap_m: float = 0.3  # a match whose two heights differ more cannot be right on a floor
    min_pair_length_m: float = 1.0  # the two matches of a pair at least this far apart (heading from them)
    length_tolerance: float = 0.1  # relative: a pair's lengths in scan and map must agree this well
    hypotheses: int = 5  # the best distinct poses handed on for refinement
    distinct_m: float = 1.0  # hypotheses closer than this (and 20 deg) count as one


def match_features(scan_features: np.ndarray, index: object) -> np.ndarray:
    """For each scan feature, the nearest map feature's index (a faiss index over the map's features)."""
    _, nearest = index.search(np.ascontiguousarray(scan_features, dtype=np.float32), 1)  # type: ignore[attr-defined]
    return np.asarray(nearest[:, 0], dtype=np.int64)


def ransac_poses(
    scan: np.ndarray, matched: np.ndarray, rng: np.random.Generator, config: SearchConfig = SearchConfig()
) -> tuple[np.ndarray, np.ndarray]:
    """Candidate poses (K, 3) with their inlier counts (K,), best first, from matches ``scan[i] <->
    matched[i]`` (both (C, 3), z above the floor; ``scan`` in the robot frame, ``matched`` in the map)."""
    c = config
    same_height = np.abs(scan[:, 2] - matched[:, 2]) <= c.max_height_gap_m
    s, m = scan[same_height, :2], matched[same_height, :2]
    if len(s) < 2:
        return np.zeros((0, 3)), np.zeros(0, dtype=int)
    a, b = rng.integers(0, len(s), (2, c.iterations))
    vs, vm = s[b] - s[a], m[b] - m[a]
    ls, lm = np.hypot(vs[:, 0], vs[:, 1]), np.hypot(vm[:, 0], vm[:, 1])
    ok = (ls >= c.min_pair_length_m) & (np.abs(ls - lm) <= c.length_tolerance * ls)
    if not ok.any():
        return np.zeros((0, 3)), np.zeros(0, dtype=int)
    a, b, vs, vm = a[ok], b[ok], vs[ok], vm[ok]
    yaw = np.arctan2(vm[:, 1], vm[:, 0]) - np.arctan2(vs[:, 1], vs[:, 0])
    cos, sin = np.cos(yaw), np.sin(yaw)
    mid_s, mid_m = (s[a] + s[b]) / 2, (m[a] + m[b]) / 2
    tx = mid_m[:, 0] - (cos * mid_s[:, 0] - sin * mid_s[:, 1])
    ty = mid_m[:, 1] - (sin * mid_s[:, 0] + cos * mid_s[:, 1])
    # every hypothesis against every match: (H, C)
    ex = cos[:, None] * s[None, :, 0] - sin[:, None] * s[None, :, 1] + tx[:, None] - m[None, :, 0]
    ey = sin[:, None] * s[None, :, 0] + cos[:, None] * s[None, :, 1] + ty[:, None] - m[None, :, 1]
    inliers = np.count_nonzero(ex * ex + ey * ey <= c.inlier_distance_m**2, axis=1)
    poses = np.stack([tx, ty, wrap_angle(yaw)], axis=1)
    return distinct_best(poses, inliers, c.hypotheses, c.distinct_m, np.radians(20.0))


def distinct_best(
    poses: np.ndarray, scores: np.ndarray, count: int, min_distance: float, min_angle: float
) -> tuple[np.ndarray, np.ndarray]:
    """Up to ``count`` poses, best score first, none within ``min_distance`` and ``min_angle`` of a better one."""
    chosen: list[int] = []
    for i in np.argsort(-scores, kind="stable"):
        gaps = [
            (float(np.hypot(*(poses[i, :2] - poses[j, :2]))), abs(float(wrap_angle(poses[i, 2] - poses[j, 2]))))
            for j in chosen
        ]
        if not any(d < min_distance and a < min_angle for d, a in gaps):
            chosen.append(int(i))
            if len(chosen) == count:
                break
    return poses[chosen], scores[chosen]
