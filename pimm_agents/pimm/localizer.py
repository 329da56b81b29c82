"""The PIMM localizer: scan -> PointNet (labels, descriptor) -> corners + fingerprint suggestions -> filter.

Each fresh 3D scan is segmented; its wall and ceiling points give corner features stamped with the scan's
time, and its descriptor gives position suggestions from the fingerprint map. Odometry drives the particle
filter; after each motion update the latest features, moved by the odometry since their scan (latency
compensation, thesis 3.4.2), weight the particles. Timings per stage are in every estimate.
"""

from __future__ import annotations

import time
import warnings

import numpy as np

from pimm_agents.corners.detector import FeatureList, detect_corners
from pimm_agents.corners.lookup import NearestCornerGrid
from pimm_agents.localizer import INSIDE_PARTICLES, Observation, PoseEstimate, particle_sample, require
from pimm_agents.observation_guard import ObservationGuard
from pimm_agents.particles.likelihood_field import LikelihoodField
from pimm_agents.perception.fingerprint_map import FingerprintMap
from pimm_agents.perception.point_features import valid_returns
from pimm_agents.perception.resample import LayoutResampler
from pimm_agents.perception.segmenter import CloudSegmenter, Segmenter
from pimm_agents.pimm.ambiguity import AmbiguityCheck
from pimm_agents.pimm.config import PimmConfig
from pimm_agents.pimm.feature_filter import FeatureFilter
from pimm_agents.pimm.scan_features import OdometryHistory, compensate, feature_array, wall_points
from pimm_agents.pimm.step import MeasurementStep
from pimm_env.errors import LocalizerError
from pimm_env.geometry import carry, compose
from pimm_env.mapping.corner_map import CornerMap
from pimm_env.mapping.occupancy import OccupancyGrid
from pimm_env.mapping.twins import MapTwins
from pimm_env.sim.lidar import Lidar3DConfig, directions_3d, to_robot_frame
from pimm_env.world.semantics import SemanticClass

LOOKUP_RESOLUTION_M = 0.25  # ours: the cell size of the nearest-corner grid (corners/lookup.py)


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
        twins: MapTwins | None = None,
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
                LOOKUP_RESOLUTION_M,
                orientation_bins=config.filter.orientation_bins,
                sigma_pos=config.filter.min_sigma_pos_m,
                sigma_theta=config.filter.min_sigma_theta_rad,
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
        self.filter = FeatureFilter(occupancy, lookup, config.filter, field, walls.temperature, config.belief)
        #: beside the filter: whether the estimate is the only place the scans allow (PimmConfig: with the walls)
        check = None
        if config.rivals.enabled and field is not None:
            check = AmbiguityCheck(occupancy, field, walls.temperature, config.rivals, twins)
        self.step = MeasurementStep(self.filter, check, config.belief.confirm_updates)
        self.history = OdometryHistory()
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
        c = self.config.filter
        self._features = feature_array(features, c.min_sigma_pos_m, c.min_sigma_theta_rad)
        self._features_stamp = stamp
        self._suggestions = retrieval.suggestions
        if self.config.wall_field.enabled:
            self._walls = wall_points(cloud, segmented.labels, self.config.wall_field.points)

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
                # perceived when it is weighed, not on arrival (docs/design.md#perceived-when-weighed): kept as a
                # copy, since the caller may reuse its buffers
                self._pending = (np.array(cloud), np.array(mask), cloud_time)
        moved, weighed = self.filter.motion_update(odom), None
        # once per scan, as nav2 uses each laser scan once; the thesis weighed after every motion update
        if moved and (self._unused_scan or self.config.filter.thesis):
            self._unused_scan = False
            self._perceive_pending(timings)
            features, walls = self._features, self._walls
            at_scan = self.history.at(self._features_stamp)  # latency compensation (thesis 3.4.2)
            features = compensate(features, at_scan, odom)
            walls = None if walls is None else compensate(walls, at_scan, odom)
            self._walls, weighed = None, walls  # each scan's walls weigh once, in either preset
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
