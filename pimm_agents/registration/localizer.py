"""``registration``: global localization by matching the 3D scan to a point cloud of the map, then tracking
by scan-to-map ICP (Open3D, point to plane) from the odometry's prediction.

Each fresh scan is thinned to one point per voxel, its normals turned to face the sensor. While lost, a
global search (``global_search.py``) proposes a few poses; each is refined by ICP against the map around it
and the one with the best fitness (the share of scan points within ``fitness_distance_m`` of the map) is
taken if that share reaches ``min_fitness``; if another hypothesis, away from it, fits nearly as well
(``rival_fitness_ratio``), the status is ``ambiguous`` and the search is repeated every ``global_period_s``
until one finds no rival. ``localized`` needs ``confirm_updates`` tracked scans in a row. The covariance is
ICP's (Gauss-Newton, ``PlanarIcp.covariance``) plus the voxel's quantization. While tracking, ICP starts from
the last pose carried by the odometry; after ``lost_after`` scans in a row under ``min_fitness`` the
localizer is lost again. Between scans, and while lost, the estimate follows the odometry.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from pimm_agents.localizer import Hypothesis, Observation, PoseEstimate, require
from pimm_agents.observation_guard import GuardConfig, ObservationGuard
from pimm_agents.particles.belief import Confirmation
from pimm_agents.perception.point_features import valid_returns
from pimm_agents.registration.global_search import SearchConfig, match_features, ransac_poses
from pimm_agents.registration.map_cloud import MapCloud, estimate_normals, fpfh, to_open3d
from pimm_agents.registration.planar_icp import PlanarIcp
from pimm_env.errors import LocalizerError
from pimm_env.geometry import carry, wrap_angle
from pimm_env.sim.lidar import Lidar3DConfig, to_robot_frame

#: Reported while lost: the pose is a guess.
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
    #: a refined hypothesis more than 1 m or 10 deg from the best whose fitness is at least this share of the
    #: best's is a rival: the status is ambiguous until a search finds none
    rival_fitness_ratio: float = 0.95
    confirm_updates: int = 10  # tracked scans in a row before the status is localized (as the filters')
    guard: GuardConfig = field(default_factory=GuardConfig)  # glitches set aside (observation_guard.py)

    def __post_init__(self) -> None:
        for name in ("voxel_m", "icp_max_distance_m", "fitness_distance_m"):
            if not getattr(self, name) > 0:
                raise LocalizerError(f"registration.{name} must be positive, got {getattr(self, name)}")
        if not 0 < self.min_fitness <= 1:
            raise LocalizerError(f"registration.min_fitness must be in (0, 1], got {self.min_fitness}")
        if not 0 < self.rival_fitness_ratio <= 1:
            raise LocalizerError(f"registration.rival_fitness_ratio must be in (0, 1], got {self.rival_fitness_ratio}")
        if self.icp_iterations < 1 or self.lost_after < 1 or self.confirm_updates < 0:
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
        self.guard = ObservationGuard(config.guard)
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
        self._rival = False  # the last global search found a rival to the pose it gave
        self._hypotheses: tuple[Hypothesis, ...] = ()
        self._cov = LOST_COV.copy()
        self.confirmation = Confirmation(self.config.confirm_updates)
        self._status = "lost"
        if initial_pose is not None:  # told where it is: not confirmed until ICP has tracked it
            self._status = "ambiguous" if self.config.confirm_updates else "localized"
            self._cov = np.diag([0.25, 0.25, (np.pi / 12) ** 2]) if initial_cov is None else np.array(initial_cov)
        self._last: PoseEstimate | None = None

    # ------------------------------------------------------------------ the contract
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
        if not self._tracking:
            self._status, self._cov = "lost", LOST_COV.copy()  # searching globally, the pose a guess
        x, y, theta = (float(v) for v in predicted)
        estimate = PoseEstimate(x, y, theta, self._cov.copy(), stamp, timings, self._status, self._hypotheses)
        self._last = self.guard.stamped(estimate)
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
                if self._rival and stamp - self._last_search >= self.config.global_period_s:
                    pose, fitness = self._search_again(scan, pose, fitness, stamp, timings)
                self._read_fit(scan, pose, moved_place=False)
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
            self.confirmation.reset()
            self._read_fit(scan, found, moved_place=True)
            return found
        return predicted

    def _search_again(
        self, scan: Any, tracked: np.ndarray, fitness: float, stamp: float, timings: dict[str, float]
    ) -> tuple[np.ndarray, float]:
        """While a rival stands: search globally again; its best replaces the tracked pose if it fits better."""
        self._last_search = stamp
        start = time.perf_counter()
        found, found_fitness = self.search(scan)
        timings["global_search"] = 1000 * (time.perf_counter() - start)
        if found is not None and found_fitness > fitness and not near(found, tracked):
            self.confirmation.reset()
            return found, found_fitness
        return tracked, fitness

    def _read_fit(self, scan: Any, pose: np.ndarray, moved_place: bool) -> None:
        """Covariance (ICP's, floored) and status at a scan ICP fitted."""
        c = self.config
        cov = self.icp.covariance(np.asarray(scan.points), pose, c.icp_max_distance_m)
        floor = np.diag([(c.voxel_m**2) / 12, (c.voxel_m**2) / 12, (c.voxel_m**2) / 12 / 25.0])
        self._cov = floor if cov is None else 0.5 * (cov + cov.T) + floor
        status = self.confirmation("localized", moved_place)
        self._status = "ambiguous" if self._rival else status

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
        refined = [self.refine(scan, hypothesis) for hypothesis in poses]
        if not refined:
            self._hypotheses, self._rival = (), False
            return None, 0.0
        order = np.argsort([-f for _, f in refined], kind="stable")
        best, best_fitness = refined[order[0]]
        self._rival = any(f >= self.config.rival_fitness_ratio * best_fitness and not near(p, best) for p, f in refined)
        total = sum(f for _, f in refined) or 1.0
        self._hypotheses = tuple(
            Hypothesis(float(p[0]), float(p[1]), float(p[2]), float(f / total), LOST_COV.copy())
            for p, f in (refined[k] for k in order[:3])
        )
        return best, best_fitness

    def refine(self, scan: Any, guess: np.ndarray) -> tuple[np.ndarray, float]:
        """Planar point-to-plane ICP of the scan against the map from ``guess``: the pose and its fitness."""
        points = np.asarray(scan.points)
        c = self.config
        pose = self.icp.align(points, guess, c.icp_max_distance_m, c.icp_iterations)
        return pose, self.icp.fitness(points, pose, c.fitness_distance_m)


def near(a: np.ndarray, b: np.ndarray, distance_m: float = 1.0, angle_deg: float = 10.0) -> bool:
    """Whether two poses are the same place: within ``distance_m`` and ``angle_deg``."""
    return bool(
        np.hypot(a[0] - b[0], a[1] - b[1]) <= distance_m and abs(wrap_angle(a[2] - b[2])) <= np.radians(angle_deg)
    )
