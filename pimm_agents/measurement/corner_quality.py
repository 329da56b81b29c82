"""How well the corner detector finds the map's corners: precision, recall and errors over fresh scans."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pimm_agents.corners.detector import CornerDetectorConfig, FeatureList, detect_corners
from pimm_env.geometry import compose, wrap_angle
from pimm_env.mapping.corner_map import CornerMap
from pimm_env.world.model import World
from pimm_env.world.semantics import SemanticClass


@dataclass(frozen=True)
class CornerStats:
    precision: float | None  # None: nothing detected
    recall: float | None  # None: no map corner in sight (an empty corner map), so recall cannot be measured
    median_position_error_m: float | None
    median_orientation_error_deg: float | None
    scans: int
    detected: int
    visible: int


#: Points on each wall face, in metres from the vertex, and below the ceiling, that a sensor must see for the
#: corner to count as visible: a vertex in sight whose second wall is hidden cannot be found by any detector.
FACE_PROBES_M = (0.5, 1.2)
FACE_PROBE_DROP_M = 1.0


def _in_sight(
    caster,
    origin: np.ndarray,
    target: np.ndarray,
    max_range: float,
    half_fov: float,
    slack: float,
    on_wall: bool = False,
) -> bool:
    delta = target - origin
    distance = float(np.linalg.norm(delta))
    if distance >= max_range or distance < 1e-6:
        return False
    elevation = float(np.arcsin(np.clip(delta[2] / distance, -1, 1)))
    if abs(elevation) > half_fov:
        return False
    azimuth = float(np.arctan2(delta[1], delta[0]))
    ranges, labels = caster.cast(origin, np.array([azimuth]), np.array([elevation]), max_range)
    if on_wall and labels[0, 0] != SemanticClass.WALL:
        return False
    return bool(ranges[0, 0] >= distance - slack)


def visible_corners(
    caster, origin: np.ndarray, corners: CornerMap, max_range: float, half_fov: float, faces: bool = True
) -> np.ndarray:
    """Indices of map corners within ``max_range`` of the sensor at ``origin`` and in its field of view, with
    a clear ray to the vertex (to within 0.15 m: the vertex itself lies on the walls) and, with ``faces``, to
    a point of each of its two wall faces (the faces run at theta +- 45 deg from the vertex; probes at
    FACE_PROBES_M along them, FACE_PROBE_DROP_M under the ceiling). The ray must end on a wall there: where
    the map's wall line is glass, a door or a window, the scan has no wall to fit, and the corner map (drawn
    from the occupancy grid) has a corner that no wall-and-ceiling detector can find."""
    out = []
    for k in range(len(corners)):
        vertex = np.array([*corners.xy[k], corners.z[k]])
        if not _in_sight(caster, origin, vertex, max_range, half_fov, 0.15):
            continue
        if faces:
            seen_faces = 0
            for side in (1, -1):
                heading = corners.theta[k] + side * np.pi / 4
                direction = np.array([np.cos(heading), np.sin(heading), 0.0])
                probes = [vertex + a * direction - [0, 0, FACE_PROBE_DROP_M] for a in FACE_PROBES_M]
                seen_faces += any(_in_sight(caster, origin, q, max_range, half_fov, 0.1, on_wall=True) for q in probes)
            if seen_faces < 2:
                continue
        out.append(k)
    return np.array(out, dtype=int)


def to_map(features: FeatureList, pose: np.ndarray) -> np.ndarray:
    """(K, 3) corner poses in the map frame from robot-frame features and the robot's pose."""
    if not len(features):
        return np.zeros((0, 3))
    return compose(pose, np.array([[c.x, c.y, c.theta] for c in features.features]))


def corner_stats(
    scans: list[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]],
    corners: CornerMap,
    config: CornerDetectorConfig | None = None,
    match_distance: float = 0.5,
) -> CornerStats:
    """``scans``: (points, labels, robot pose, indices of visible map corners) each.

    A detection is correct if a map corner lies within ``match_distance``; recall counts the visible corners
    that some detection matched. Errors are over the correct detections.
    """
    detected = correct = visible = found = 0
    position_errors, angle_errors = [], []
    for points, labels, pose, seen in scans:
        in_map = to_map(detect_corners(points, labels, config=config), pose)
        detected += len(in_map)
        visible += len(seen)
        matched = set()
        for x, y, theta in in_map if len(corners) else ():  # with no map corner, no detection is right
            distance = np.hypot(*(corners.xy - [x, y]).T)
            k = int(np.argmin(distance))
            if distance[k] <= match_distance:
                correct += 1
                matched.add(k)
                position_errors.append(distance[k])
                angle_errors.append(abs(float(wrap_angle(theta - corners.theta[k]))))
        found += len(matched & {int(k) for k in seen})
    return CornerStats(
        precision=correct / detected if detected else None,
        recall=found / visible if visible else None,
        median_position_error_m=float(np.median(position_errors)) if position_errors else None,
        median_orientation_error_deg=float(np.degrees(np.median(angle_errors))) if angle_errors else None,
        scans=len(scans),
        detected=detected,
        visible=visible,
    )


@dataclass(frozen=True)
class FreshScan:
    """One scan as the env gave it (full cloud, mask, true labels), the true pose, its area, visible corners."""

    cloud: np.ndarray
    mask: np.ndarray
    labels: np.ndarray
    pose: np.ndarray
    area: str
    seen: np.ndarray

    def corner_input(self, labels: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """What :func:`corner_stats` takes, with the true labels or the given (predicted) ones."""
        chosen = self.labels if labels is None else labels
        return self.cloud[self.mask], chosen[self.mask], self.pose, self.seen


def collect_scans(world: str | World, count: int, seed: int) -> list[FreshScan]:
    """``count`` scans at random free poses (seeded), with true labels and the visible map corners."""
    from pimm_env.envs.iilab_env import IILabEnv

    env = IILabEnv(world=world)
    corners = env.maps.corners
    l3 = env.config.lidar3d
    half_fov = np.radians(l3.vertical_fov_deg) / 2
    scans = []
    try:
        for i in range(count):
            obs, info = env.reset(seed=seed * 100_003 + i)
            pose = info["true_pose"]
            origin = np.array([pose[0], pose[1], env.world.floor_z + l3.height])
            seen = visible_corners(env.caster, origin, corners, l3.max_range, half_fov)
            mask = obs["cloud_mask"].astype(bool)
            scans.append(FreshScan(obs["cloud"], mask, info["labels"], pose, info["area"] or "", seen))
    finally:
        env.close()
    return scans
