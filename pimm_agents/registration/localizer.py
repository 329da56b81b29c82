"""``registration``: global localization by matching the 3D scan to a point cloud of the map, then tracking
by scan-to-map ICP (Open3D, point to plane) from the odometry's prediction.

Each fresh scan is thinned to one point per voxel, its normals turned to face the sensor. While lost, a
global search (``global_search.py``) proposes a few poses; each is refined by ICP against the map around it
and the one with the best fitness (the share of scan points within ``fitness_distance_m`` of the map) is
taken if that share reaches ``min_fitness``. While tracking, ICP starts from the last pose carried by the
odometry; after ``lost_after`` scans in a row under ``min_fitness`` the localizer is lost again. Between
scans, and while lost, the estimate follows the odometry.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from pimm_agents.localizer import Observation, PoseEstimate, require
from pimm_agents.observation_guard import ObservationGuard
from pimm_agents.perception.point_features import valid_returns
from pimm_agents.registration.global_search import SearchConfig, match_features, ransac_poses
from pimm_agents.registration.map_cloud import MapCloud, estimate_normals, fpfh, to_open3d
from pimm_agents.registration.planar_icp import PlanarIcp
from pimm_env.errors import LocalizerError
from pimm_env.geometry import carry
from pimm_env.sim.lidar import Lidar3DConfig, to_robot_frame

#: Reported while tracking (ours: ICP's spread on the iilab's scans is about this) and while lost.
TRACKING_COV = np.diag([0.05**2, 0.05**2, np.radians(2.0) ** 2])
LOST_COV = np.diag([100.0, 100.0, np.pi**2])


@dataclass(frozen=True)
class RegistrationConfig:
    """Ours, in the manner of hdl_global_localization and hdl_localization (their structure, our values)."""

    voxel_m: float = 0.25  # scan and map thinned to one point per voxel; FPFH radius 5 voxels
    icp_max_distance_m: float = 1.0  # ICP correspondences up to this far
    icp_iterations: int = 30
    fitness_distance_m: float = 0.3  # fitness: share of scan points this close to the map after ICP
    min_fitness: float = 0.6  # to accept a global hypothesis or keep tracking
    lost_after: int = 3  # scans in a row under min_fitness before searching globally again
    global_period_s: float = 1.0  # while lost, a global search at most this often (each costs ~0.5 s here)
    search: SearchConfig = field(default_factory=SearchConfig)

    def __post_init__(self) -> None:
        for name in ("voxel_m", "icp_max_distance_m", "fitness_distance_m"):
            if not getattr(self, name) > 0:
                raise LocalizerError(f"registration.{name} must be positive, got {getattr(self, name)}")
        if not 0 < self.min_fitness <= 1:
            raise LocalizerError(f"registration.min_fitness must be in (0, 1], got {self.min_fitness}")
        if self.icp_iterations < 1 or self.lost_after < 1:
            raise LocalizerError("registration.icp_iterations and lost_after must be at least 1")


class RegistrationLocalizer:
    sensors = ("odom", "cloud")

    def __init__(
        self,
        map_cloud: MapCloud,
        config: RegistrationConfig = RegistrationConfig(),
        lidar3d: Lidar3DConfig | None = None,
        name: str = "registration",
    ) -> None:
        import faiss

        if len(map_cloud.points) < 10:
            raise LocalizerError(f"the map cloud has {len(map_cloud.points)} points; registration needs a map")
        self.name = name
        self.config = config
        self.lidar3d = lidar3d or Lidar3DConfig()
        self.map = map_cloud
        self.index = faiss.IndexFlatL2(map_cloud.features.shape[1])
        self.index.add(np.ascontiguousarray(map_cloud.features, dtype=np.float32))
        self.icp = PlanarIcp(map_cloud.points, map_cloud.normals)
        self.guard = ObservationGuard()
        self.reset()

    def reset(
        self, seed: int | None = None, initial_pose: np.ndarray | None = None, initial_cov: np.ndarray | None = None
    ) -> None:
        """Lost (a global search at the first scan), or tracking from ``initial_pose``."""
        self.rng = np.random.default_rng(seed)
        self.guard.reset()
        self._tracking = initial_pose is not None
        self._pose = np.zeros(3) if initial_pose is None else np.asarray(initial_pose, dtype=float).copy()
        if initial_pose is None:  # nothing known: the middle of the map until a search succeeds
            self._pose[:2] = self.map.points[:, :2].mean(axis=0)
        self._odom: np.ndarray | None = None
        self._misses = 0
        self._last_cloud_time = -np.inf
        self._last_search = -np.inf
        self.fitness = 0.0
        self._last: PoseEstimate | None = None

    # ------------------------------------------------------------------ the contract
    def update(self, obs: Observation) -> PoseEstimate:
        began = time.perf_counter()
        timings: dict[str, float] = {}
        self.guard.check(obs, ("odom", "time", "cloud_time"))
        cloud, mask = self.guard.cloud(obs)
        taken = self.guard.take(obs)
        if taken is None and self._last is not None:  # a glitch: keep the estimate
            return self._last
        obs = taken or obs
        stamp = float(require(obs, "time", (1,))[0])
        odom = require(obs, "odom", (3,))
        if self._odom is None:
            self._odom = odom.copy()
        predicted = carry(self._pose, self._odom, odom)
        cloud_time = float(require(obs, "cloud_time", (1,))[0])
        if np.isfinite(cloud_time) and cloud_time > self._last_cloud_time:
            self._last_cloud_time = cloud_time
            points = to_robot_frame(cloud, self.lidar3d)[valid_returns(cloud, mask)].astype(np.float64)  # its mount
            points[:, 2] += self.lidar3d.height  # z above the floor, as the map's
            if len(points) >= 20:
                predicted = self._correct(points, predicted, stamp, timings)
        self._pose, self._odom = predicted, odom.copy()
        timings["total"] = 1000 * (time.perf_counter() - began)
        cov = TRACKING_COV if self._tracking else LOST_COV
        status = "localized" if self._tracking else "lost"  # lost: searching globally, the pose a guess
        x, y, theta = (float(v) for v in predicted)
        self._last = PoseEstimate(x, y, theta, cov.copy(), stamp, timings, status)
        return self._last

    @property
    def tracking(self) -> bool:
        return self._tracking

    # ------------------------------------------------------------------ steps
    def _correct(
        self, points: np.ndarray, predicted: np.ndarray, stamp: float, timings: dict[str, float]
    ) -> np.ndarray:
        start = time.perf_counter()
        scan = self.prepare(points)
        timings["preprocess"] = 1000 * (time.perf_counter() - start)
        if self._tracking:
            start = time.perf_counter()
            pose, fitness = self.refine(scan, predicted)
            timings["icp"] = 1000 * (time.perf_counter() - start)
            self.fitness = fitness
            if fitness >= self.config.min_fitness:
                self._misses = 0
                return pose
            self._misses += 1
            if self._misses >= self.config.lost_after:
                self._tracking = False
            return predicted
        if stamp - self._last_search < self.config.global_period_s:
            return predicted
        self._last_search = stamp
        start = time.perf_counter()
        found, fitness = self.search(scan)
        timings["global_search"] = 1000 * (time.perf_counter() - start)
        self.fitness = fitness
        if found is not None and fitness >= self.config.min_fitness:
            self._tracking, self._misses = True, 0
            return found
        return predicted

    def prepare(self, points: np.ndarray) -> Any:
        """The scan thinned to one point per voxel, with normals facing the sensor."""
        cloud = to_open3d(points).voxel_down_sample(self.config.voxel_m)
        estimate_normals(cloud, self.config.voxel_m)
        cloud.orient_normals_towards_camera_location(np.array([0.0, 0.0, self.lidar3d.height]))
        return cloud

    def search(self, scan: Any) -> tuple[np.ndarray | None, float]:
        """Global search: the hypotheses of the RANSAC, each refined by ICP; the best by fitness."""
        features = fpfh(scan, self.config.voxel_m)
        points = np.asarray(scan.points)
        matched = self.map.points[match_features(features, self.index)]
        poses, _ = ransac_poses(points, matched, self.rng, self.config.search)
        best: np.ndarray | None = None
        best_fitness = 0.0
        for hypothesis in poses:
            pose, fitness = self.refine(scan, hypothesis)
            if fitness > best_fitness:
                best, best_fitness = pose, fitness
        return best, best_fitness

    def refine(self, scan: Any, guess: np.ndarray) -> tuple[np.ndarray, float]:
        """Planar point-to-plane ICP of the scan against the map from ``guess``: the pose and its fitness."""
        points = np.asarray(scan.points)
        c = self.config
        pose = self.icp.align(points, guess, c.icp_max_distance_m, c.icp_iterations)
        return pose, self.icp.fitness(points, pose, c.fitness_distance_m)
