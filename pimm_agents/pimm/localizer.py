"""The PIMM localizer: scan -> PointNet (labels, descriptor) -> corners + fingerprint suggestions -> filter.

Each fresh 3D scan is segmented; its wall and ceiling points give corner features stamped with the scan's
time, and its descriptor gives position suggestions from the fingerprint map. Odometry drives the particle
filter; after each motion update the latest features, moved by the odometry since their scan (latency
compensation, thesis 3.4.2), weight the particles. Timings per stage are in every estimate.
"""

from __future__ import annotations

import time
from collections import deque
from dataclasses import dataclass, field

import numpy as np

from pimm_agents.corners.detector import CornerDetectorConfig, FeatureList, detect_corners
from pimm_agents.corners.lookup import NearestCornerGrid
from pimm_agents.localizer import Observation, PoseEstimate, require
from pimm_agents.perception.fingerprint_map import FingerprintMap
from pimm_agents.perception.point_features import valid_returns
from pimm_agents.perception.segmenter import Segmenter
from pimm_agents.pimm.feature_filter import FeatureFilter, FeatureFilterConfig
from pimm_env.geometry import carry, compose, relative_motion
from pimm_env.mapping.corner_map import CornerMap
from pimm_env.mapping.occupancy import OccupancyGrid
from pimm_env.sim.lidar import Lidar3DConfig, directions_3d
from pimm_env.world.semantics import SemanticClass


@dataclass(frozen=True)
class PimmConfig:
    filter: FeatureFilterConfig = field(default_factory=FeatureFilterConfig)
    corners: CornerDetectorConfig = field(default_factory=CornerDetectorConfig)
    use_suggestions: bool = True  # seed injected particles around the fingerprint map's suggestions
    latency_compensation: bool = True
    odometry_history_s: float = 5.0  # how far back a feature's scan time can be looked up
    # Floors on the feature uncertainty the filter uses (ours; the thesis tuned its covariances by hand).
    # The detector's fit-derived covariances ignore model and association errors and are far narrower; with
    # them a 10 000-particle cloud over the iiLab rarely holds a particle close enough to the truth to win.
    min_sigma_pos_m: float = 0.3
    min_sigma_theta_rad: float = 0.2


def feature_array(features: FeatureList, min_sigma_pos: float = 0.0, min_sigma_theta: float = 0.0) -> np.ndarray:
    """(K, 5) x, y, theta, sigma_pos, sigma_theta of the features; sigma_pos = sqrt(var_x + var_y) (eq. 3.15)."""
    rows = [
        (
            f.x,
            f.y,
            f.theta,
            max(min_sigma_pos, float(np.sqrt(f.position_covariance[0, 0] + f.position_covariance[1, 1]))),
            max(min_sigma_theta, float(np.sqrt(f.orientation_variance))),
        )
        for f in features.features
    ]
    return np.array(rows, dtype=float).reshape(-1, 5)


def compensate(features: np.ndarray, odom_at_scan: np.ndarray, odom_now: np.ndarray) -> np.ndarray:
    """Features seen from the robot at scan time, expressed in the robot frame now."""
    if len(features) == 0:
        return features
    motion = relative_motion(odom_at_scan, odom_now)  # the robot now, in its frame at scan time
    back = relative_motion(motion, np.zeros(3))  # scan-time frame in the frame of now
    moved = features.copy()
    moved[:, :3] = compose(back, features[:, :3])
    return moved


class OdometryHistory:
    """Recent (time, odometry) pairs; the odometry at a past time by interpolation."""

    def __init__(self, span_s: float) -> None:
        self.span_s = span_s
        self._items: deque[tuple[float, np.ndarray]] = deque()

    def clear(self) -> None:
        self._items.clear()

    def add(self, stamp: float, odom: np.ndarray) -> None:
        if self._items and stamp < self._items[-1][0]:
            self._items.clear()  # time went back: a new episode
        self._items.append((stamp, odom.copy()))
        while self._items and self._items[0][0] < stamp - self.span_s:
            self._items.popleft()

    def at(self, stamp: float) -> np.ndarray:
        """Odometry at ``stamp``, interpolated; clamped to the oldest and newest kept."""
        if not self._items:
            raise ValueError("no odometry recorded yet")
        times = np.array([t for t, _ in self._items])
        k = int(np.searchsorted(times, stamp))
        if k == 0:
            return self._items[0][1].copy()
        if k >= len(times):
            return self._items[-1][1].copy()
        (t0, a), (t1, b) = self._items[k - 1], self._items[k]
        u = (stamp - t0) / (t1 - t0) if t1 > t0 else 1.0
        return compose(a, u * relative_motion(a, b))[0]


class PimmLocalizer:
    sensors = ("odom", "cloud")

    def __init__(
        self,
        occupancy: OccupancyGrid,
        corners: CornerMap,
        segmenter: Segmenter,
        fingerprints: FingerprintMap,
        config: PimmConfig = PimmConfig(),
        name: str = "pimm",
    ) -> None:
        self.name = name
        self.config = config
        self.segmenter = segmenter
        self.fingerprints = fingerprints
        self.filter = FeatureFilter(
            occupancy, NearestCornerGrid(corners, config.filter.lookup_resolution_m), config.filter
        )
        self.history = OdometryHistory(config.odometry_history_s)
        self._warm_up()
        self.reset()

    def _warm_up(self) -> None:
        """Run perception once on a synthetic scan (a 5 m sphere) so that the one-off costs of torch's first
        call and of importing Open3D do not land in the first real update's timings."""
        layers, per_layer = self.segmenter.layers, self.segmenter.points_per_layer
        directions = directions_3d(Lidar3DConfig(layers=layers, points_per_layer=per_layer)).astype(np.float32)
        self.perceive(5.0 * directions, np.ones(len(directions), dtype=bool), 0.0, {})

    def reset(
        self, seed: int | None = None, initial_pose: np.ndarray | None = None, initial_cov: np.ndarray | None = None
    ) -> None:
        """Forget everything: global localization, or particles about ``initial_pose`` (nav2's covariance)."""
        self.rng = np.random.default_rng(seed)
        self.filter.reset(self.rng, initial_pose, initial_cov)
        self.history.clear()
        self._features = np.zeros((0, 5))
        self._features_stamp = 0.0
        self._suggestions = np.zeros((0, 2))
        self._last_cloud_time = -np.inf
        self._estimate: np.ndarray | None = None
        self._estimate_odom: np.ndarray | None = None

    def perceive(self, cloud: np.ndarray, mask: np.ndarray, stamp: float, timings: dict[str, float]) -> None:
        """Segment a fresh scan; keep its corner features (robot frame, scan time) and position suggestions."""
        segmented = self.segmenter.segment(cloud, mask)
        timings["segmentation"] = sum(segmented.timings_ms.values())
        start = time.perf_counter()
        keep = segmented.labels >= 0
        structural = np.isin(segmented.labels, (int(SemanticClass.WALL), int(SemanticClass.CEILING)))
        features = detect_corners(
            cloud[keep & structural], segmented.labels[keep & structural], stamp, self.config.corners
        )
        timings["corners"] = 1000 * (time.perf_counter() - start)
        start = time.perf_counter()
        retrieval = self.fingerprints.query(segmented.descriptor)
        timings["pose_inference"] = 1000 * (time.perf_counter() - start)
        self._features = feature_array(features, self.config.min_sigma_pos_m, self.config.min_sigma_theta_rad)
        self._features_stamp = stamp
        self._suggestions = retrieval.suggestions if self.config.use_suggestions else np.zeros((0, 2))

    def update(self, obs: Observation) -> PoseEstimate:
        began = time.perf_counter()
        timings: dict[str, float] = {}
        stamp = float(require(obs, "time", (1,))[0])
        odom = require(obs, "odom", (3,))
        self.history.add(stamp, odom)
        cloud_time = float(require(obs, "cloud_time", (1,))[0])
        if cloud_time > self._last_cloud_time:
            cloud = np.asarray(require(obs, "cloud"), dtype=np.float32)
            mask = require(obs, "cloud_mask", (len(cloud),)).astype(bool)
            self._last_cloud_time = cloud_time
            if np.any(valid_returns(cloud, mask)):
                self.perceive(cloud, mask, cloud_time, timings)
        if self.filter.motion_update(odom):
            features = self._features
            if self.config.latency_compensation:
                features = compensate(features, self.history.at(self._features_stamp), odom)
            start = time.perf_counter()
            previous = None
            if self._estimate is not None and self._estimate_odom is not None:
                previous = carry(self._estimate, self._estimate_odom, odom)
            estimate = self.filter.correct(features, self._suggestions, previous)
            timings["measurement_update"] = 1000 * (time.perf_counter() - start)
            if estimate is not None:
                self._estimate, self._estimate_odom = estimate, odom.copy()
        if self._estimate is None or self._estimate_odom is None:
            self._estimate, self._estimate_odom = self.filter.best_mean(), odom.copy()
        pose = carry(self._estimate, self._estimate_odom, odom)
        timings["total"] = 1000 * (time.perf_counter() - began)
        return PoseEstimate(
            float(pose[0]), float(pose[1]), float(pose[2]), self.filter.covariance(pose), stamp, timings
        )
