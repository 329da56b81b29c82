"""The PIMM localizer: scan -> PointNet (labels, descriptor) -> corners + fingerprint suggestions -> filter.

Each fresh 3D scan is segmented; its wall and ceiling points give corner features stamped with the scan's
time, and its descriptor gives position suggestions from the fingerprint map. Odometry drives the particle
filter; after each motion update the latest features, moved by the odometry since their scan (latency
compensation, thesis 3.4.2), weight the particles. Timings per stage are in every estimate.
"""

from __future__ import annotations

import time
import warnings
from collections import deque
from dataclasses import dataclass, field

import numpy as np

from pimm_agents.corners.detector import CornerDetectorConfig, FeatureList, detect_corners
from pimm_agents.corners.lookup import NearestCornerGrid
from pimm_agents.localizer import INSIDE_PARTICLES, Observation, PoseEstimate, particle_sample, require
from pimm_agents.observation_guard import GuardConfig, ObservationGuard
from pimm_agents.particles.belief import BeliefConfig
from pimm_agents.particles.likelihood_field import LikelihoodField, LikelihoodFieldParams
from pimm_agents.perception.fingerprint_map import FingerprintMap
from pimm_agents.perception.point_features import valid_returns
from pimm_agents.perception.resample import LayoutResampler
from pimm_agents.perception.segmenter import CloudSegmenter, Segmenter
from pimm_agents.pimm.ambiguity import AmbiguityCheck
from pimm_agents.pimm.feature_filter import FeatureFilter, FeatureFilterConfig
from pimm_agents.pimm.rival_config import RivalConfig
from pimm_agents.pimm.step import MeasurementStep
from pimm_env.errors import LocalizerError
from pimm_env.geometry import carry, compose, relative_motion
from pimm_env.mapping.corner_map import CornerMap
from pimm_env.mapping.occupancy import OccupancyGrid
from pimm_env.sim.lidar import Lidar3DConfig, directions_3d, to_robot_frame
from pimm_env.world.semantics import SemanticClass


@dataclass(frozen=True)
class WallFieldConfig:
    """Ours (not in the thesis): the wall points of each scan, as the network labels them,
    scored against the occupancy map with a likelihood field on nav2's defaults. Corners are rare in
    corridors and in small rooms seen from a few metres; the walls are always there, and without clutter
    (the network takes it out) they fit the map. Applied once per scan. ``enabled: false`` gives the
    thesis's filter (corners and suggestions only)."""

    enabled: bool = True
    points: int = 60  # nav2 max_beams, spread evenly over the points' bearings
    # How the points' pz combine (ours): "product" weighs by exp(temperature x sum of log pz), the textbook
    # likelihood field tempered because neighbouring points are not independent; "sum_of_cubes" by nav2's
    # 1 + sum of pz^3, which in a corridor of identical offices told the truth from one office along by a
    # factor of 1.017 a scan (gen-107, training building), where the product's log ratio is 2.1 a scan.
    model: str = "product"
    temperature: float = 0.2
    z_hit: float = 0.5  # nav2
    z_rand: float = 0.5  # nav2
    sigma_hit: float = 0.2  # nav2 (m)
    max_distance: float = 2.0  # nav2 laser_likelihood_max_dist (m)
    range_max: float = 10.0  # the thesis's 3D LiDAR range (m)
    # Ours: distances to the faces of the map's obstacles that free space can see (likelihood_field.py), so a
    # pose that throws the wall points into a thick outer wall does not fit them perfectly. False: nav2's field.
    surfaces_only: bool = True
    # Height band (m, relative to the sensor) of the wall points used: low enough that they are the walls the
    # occupancy map cuts (0.1-1.5 m above the floor with the sensor at 0.5 m), below lintels over doorways.
    min_z_m: float = -0.4
    max_z_m: float = 1.0

    def __post_init__(self) -> None:
        if self.points < 1:
            raise LocalizerError(f"wall_field.points must be at least 1, got {self.points}")
        if self.model not in ("product", "sum_of_cubes"):
            raise LocalizerError(f"wall_field.model must be 'product' or 'sum_of_cubes', got {self.model!r}")
        if not self.temperature > 0:
            raise LocalizerError(f"wall_field.temperature must be positive, got {self.temperature}")
        if self.min_z_m >= self.max_z_m:
            raise LocalizerError(f"wall_field.min_z_m ({self.min_z_m}) must be below max_z_m ({self.max_z_m})")

    def field_params(self) -> LikelihoodFieldParams:
        """The likelihood field's parameters."""
        return LikelihoodFieldParams(
            self.z_hit, self.z_rand, self.sigma_hit, self.max_distance, self.range_max, self.surfaces_only
        )

    def rival_temperature(self) -> float | None:
        """The temperature the ambiguity check scores with (the product model's; None: no check possible)."""
        return self.temperature if self.enabled and self.model == "product" else None


def wall_points(cloud: np.ndarray, labels: np.ndarray, config: WallFieldConfig) -> np.ndarray:
    """(M <= config.points, 2) x, y of the scan's wall-labelled points within the height band, spread evenly
    over their bearings (sensor frame)."""
    band = (labels == int(SemanticClass.WALL)) & (cloud[:, 2] >= config.min_z_m) & (cloud[:, 2] <= config.max_z_m)
    xy = np.asarray(cloud[band, :2], dtype=float)
    if len(xy) <= config.points:
        return xy
    order = np.argsort(np.arctan2(xy[:, 1], xy[:, 0]))
    return xy[order[np.linspace(0, len(xy) - 1, config.points).astype(int)]]


@dataclass(frozen=True)
class PimmConfig:
    filter: FeatureFilterConfig = field(default_factory=FeatureFilterConfig)
    corners: CornerDetectorConfig = field(default_factory=CornerDetectorConfig)
    wall_field: WallFieldConfig = field(default_factory=WallFieldConfig)
    belief: BeliefConfig = field(default_factory=BeliefConfig)  # modes, status (particles/belief.py)
    rivals: RivalConfig = field(default_factory=RivalConfig)  # look-alike places the scans cannot rule out
    guard: GuardConfig = field(default_factory=GuardConfig)  # glitches set aside (observation_guard.py)
    use_suggestions: bool = True  # seed injected particles around the fingerprint map's suggestions
    # Ours: weigh (and resample and inject) once per scan, at the first motion update after it, as nav2 uses
    # each laser scan once. The thesis weighed the latest features after every motion update (0.1 m or
    # 0.01 rad): in a turn one scan's corners then count up to ten times and 5 % of the particles are
    # replaced each time, which let a look-alike place win in rows of identical offices. False: the thesis's.
    measure_once_per_scan: bool = True
    # Ours: a scan is segmented, and its corners found, only when the filter is about to weigh with it. The
    # filter weighs at most once per motion update (0.1 m or 0.01 rad), so a scan that a newer one replaces
    # before the robot has moved that far was perceived for nothing: half of them on an iilab route, 7 in 10
    # driving straight at 0.3 m/s with 10 Hz scans. The estimates are the same either way (a test). False:
    # every scan on arrival.
    lazy_perception: bool = True
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
    """Features (x, y, theta, ...) or points (x, y) seen from the robot at scan time, in the robot frame now."""
    if len(features) == 0:
        return features
    motion = relative_motion(odom_at_scan, odom_now)  # the robot now, in its frame at scan time
    back = relative_motion(motion, np.zeros(3))  # scan-time frame in the frame of now
    moved = features.copy()
    if features.shape[1] == 2:
        moved[:] = compose(back, np.column_stack([features, np.zeros(len(features))]))[:, :2]
    else:
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
            raise LocalizerError("no odometry recorded yet")
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
        segmenter: Segmenter | CloudSegmenter,
        fingerprints: FingerprintMap,
        config: PimmConfig = PimmConfig(),
        name: str = "pimm",
        lidar3d: Lidar3DConfig | None = None,
    ) -> None:
        self.name = name
        self.resample = None
        if isinstance(segmenter, CloudSegmenter):  # any layout as it is, the height above the floor told
            self.lidar3d = lidar3d or Lidar3DConfig()
            segmenter.sensor_height = self.lidar3d.height
        else:
            network_layout = Lidar3DConfig(layers=segmenter.layers, points_per_layer=segmenter.points_per_layer)
            self.lidar3d = lidar3d or network_layout
            same = (self.lidar3d.layers, self.lidar3d.points_per_layer, self.lidar3d.vertical_fov_deg) == (
                network_layout.layers, network_layout.points_per_layer, network_layout.vertical_fov_deg,
            )  # fmt: skip
            self.resample = None if same else LayoutResampler(self.lidar3d, network_layout)
        self.config = config
        self.segmenter = segmenter
        self.fingerprints = fingerprints
        walls = config.wall_field
        lookup = None
        if len(corners):
            lookup = NearestCornerGrid(
                corners,
                config.filter.lookup_resolution_m,
                orientation_bins=config.filter.lookup_orientation_bins,
                sigma_pos=config.min_sigma_pos_m,
                sigma_theta=config.min_sigma_theta_rad,
            )
        elif not walls.enabled:
            raise LocalizerError(
                "the corner map is empty and the wall field is off (pimm.wall_field.enabled): PIMM would have only"
                " the fingerprint suggestions to go on; turn the wall field on or use amcl"
            )
        else:
            warnings.warn(
                "the corner map is empty (a world without wall-ceiling corners): PIMM localizes on the wall field"
                " and the fingerprint suggestions alone",
                stacklevel=2,
            )
        field = LikelihoodField(occupancy, walls.field_params()) if walls.enabled else None
        temperature = walls.temperature if walls.model == "product" else None
        self.filter = FeatureFilter(occupancy, lookup, config.filter, field, temperature, config.belief)
        #: beside the filter: whether the estimate is the only place the scans allow (needs a tempered wall field)
        check = None
        if config.rivals.enabled and field is not None and temperature is not None:
            check = AmbiguityCheck(occupancy, field, temperature, config.rivals)
        self.step = MeasurementStep(self.filter, check, config.belief.confirm_updates)
        self.history = OdometryHistory(config.odometry_history_s)
        self.guard = ObservationGuard(config.guard)
        self._warm_up()
        self.reset()

    def _warm_up(self) -> None:
        """Run perception once on a synthetic scan (a 5 m sphere) so that the one-off costs of torch's first
        call and of importing Open3D do not land in the first real update's timings."""
        import multiprocessing
        import sys

        from tqdm import tqdm

        if isinstance(self.segmenter, CloudSegmenter):
            directions = directions_3d(self.lidar3d).astype(np.float32)
        else:
            layout = Lidar3DConfig(layers=self.segmenter.layers, points_per_layer=self.segmenter.points_per_layer)
            directions = directions_3d(layout).astype(np.float32)
        quiet = multiprocessing.current_process().name != "MainProcess" or not sys.stderr.isatty()
        with tqdm(total=1, desc=f"{self.name}: warm-up (torch, Open3D)", leave=False, disable=quiet) as bar:
            self.perceive(5.0 * directions, np.ones(len(directions), dtype=bool), 0.0, {})
            bar.update()

    @property
    def last_estimate(self) -> PoseEstimate | None:
        """The estimate the last update returned (None before the first)."""
        return self._last

    def reset(
        self, seed: int | None = None, initial_pose: np.ndarray | None = None, initial_cov: np.ndarray | None = None
    ) -> None:
        """Forget everything: global localization, or particles about ``initial_pose`` (nav2's covariance)."""
        self.rng = np.random.default_rng(seed)
        self.filter.reset(self.rng, initial_pose, initial_cov)
        self.step.reset()
        self.guard.reset()
        self._last: PoseEstimate | None = None
        self.history.clear()
        self._features = np.zeros((0, 5))
        self._features_stamp = 0.0
        self._suggestions = np.zeros((0, 2))
        self._walls: np.ndarray | None = None  # the last scan's wall points until the filter has used them
        self._unused_scan = False  # a scan has arrived that no measurement update has used yet
        self._pending: tuple[np.ndarray, np.ndarray, float] | None = None  # that scan, if not yet perceived
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
        features = FeatureList(stamp, [])
        if self.filter.corners is not None:  # no corner map, nothing to match corners against
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
        if self.config.wall_field.enabled:
            self._walls = wall_points(cloud, segmented.labels, self.config.wall_field)

    def _perceive_pending(self, timings: dict[str, float]) -> None:
        """Perceive the scan that arrived last, unless it has been already."""
        if self._pending is not None:
            cloud, mask, stamp = self._pending
            self._pending = None
            self.perceive(cloud, mask, stamp, timings)

    def update(self, obs: Observation) -> PoseEstimate:
        began = time.perf_counter()
        timings: dict[str, float] = {}
        self.guard.check(obs, ("odom", "time", "cloud_time"))
        cloud, mask = self.guard.cloud(obs)
        taken = self.guard.take(obs)
        if taken is None and self._last is not None:  # a glitch: keep the estimate
            self._last = self.guard.stamped(self._last)
            return self._last
        obs = taken or obs
        stamp = float(require(obs, "time", (1,))[0])
        odom = require(obs, "odom", (3,))
        self.history.add(stamp, odom)
        cloud_time = float(require(obs, "cloud_time", (1,))[0])
        if np.isfinite(cloud_time) and cloud_time > self._last_cloud_time:
            self._last_cloud_time = cloud_time
            cloud = to_robot_frame(cloud, self.lidar3d)  # the sensors file's mount pose
            if self.resample is not None:  # another sensor's layout, read as the network's (perception/resample.py)
                cloud, mask = self.resample(cloud, mask)
            if np.any(valid_returns(cloud, mask)):
                self._unused_scan = True
                if self.config.lazy_perception:  # kept (a copy: the caller may reuse its buffers) until weighed
                    self._pending = (np.array(cloud), np.array(mask), cloud_time)
                else:
                    self.perceive(cloud, mask, cloud_time, timings)
        moved, weighed = self.filter.motion_update(odom), None
        if moved and (self._unused_scan or not self.config.measure_once_per_scan):
            self._unused_scan = False
            self._perceive_pending(timings)
            features, walls = self._features, self._walls
            if self.config.latency_compensation:
                at_scan = self.history.at(self._features_stamp)
                features = compensate(features, at_scan, odom)
                walls = None if walls is None else compensate(walls, at_scan, odom)
            self._walls, weighed = None, walls  # each scan's walls weigh once, whatever measure_once_per_scan says
            start = time.perf_counter()
            previous = None
            if self._estimate is not None and self._estimate_odom is not None:
                previous = carry(self._estimate, self._estimate_odom, odom)
            estimate = self.step(features, walls, self._suggestions, previous, odom)
            timings["measurement_update"] = 1000 * (time.perf_counter() - start)
            if self.step.check is not None:
                timings["rival_check"] = self.step.check_ms
            if estimate is not None:
                self._estimate, self._estimate_odom = estimate, odom.copy()
        if self._estimate is None or self._estimate_odom is None:
            self._estimate, self._estimate_odom = self.filter.best_mean(), odom.copy()
        pose = carry(self._estimate, self._estimate_odom, odom)
        timings["total"] = 1000 * (time.perf_counter() - began)
        reading = self.step.reading
        reported = PoseEstimate(
            float(pose[0]), float(pose[1]), float(pose[2]), reading.covariance.copy(), stamp, timings,
            reading.status, reading.hypotheses, inside=self._inside(weighed),
        )  # fmt: skip
        self._last = self.guard.stamped(reported)
        return self._last

    def _inside(self, walls: np.ndarray | None) -> dict[str, np.ndarray]:
        """A sample of the particles, the last perceived scan's corners placed at the estimate, its fingerprint
        suggestions, and the wall points this update weighed (``walls``; robot frame)."""
        pose = self._estimate if self._estimate is not None else self.filter.best_mean()
        corners = compose(pose, self._features[:, :3])[:, :2] if len(self._features) else np.zeros((0, 2))
        inside = {
            "particles": particle_sample(self.filter.particles, INSIDE_PARTICLES),
            "corners": corners,
            "suggestions": np.asarray(self._suggestions, dtype=float).reshape(-1, 2),
        }
        if walls is not None:
            inside["walls"] = walls
        return inside
