"""How the simulator's robot senses: the ray caster it casts with, its 3D and 2D LiDARs at their mounts (walkers
and unmapped furniture included), and any other sensor's rays from the robot's pose.

A part of the simulator (``LidarRobotEnv`` takes it in): it reads the env's world, config, robot, movers and
clock, and writes the scans it takes.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from pimm_env.envs.sim_config import RAY_CASTERS
from pimm_env.errors import EnvError
from pimm_env.sim.lidar import Lidar3DConfig, mount_rotation, noisy_ranges
from pimm_env.sim.raycast import BulletRayCaster, EmbreeRayCaster, PrismRayCaster, RayCaster


class LidarSensing:
    """The sensing half of ``LidarRobotEnv``."""

    config: Any
    world: Any
    robot: Any
    movers: Any
    scene: Any
    caster: Any
    _azimuths3d: np.ndarray
    _elevations: np.ndarray
    _directions3d: np.ndarray
    _azimuths2d: np.ndarray
    _time: float
    _next_cloud: float
    _next_scan: float
    _cloud: np.ndarray
    _cloud_mask: np.ndarray
    _labels: np.ndarray
    _scan: np.ndarray
    _cloud_time: float
    _scan_time: float
    _fresh: tuple[bool, bool]
    _noise: tuple[np.random.Generator, np.random.Generator] | None

    def _make_caster(self) -> RayCaster:
        choice = self.config.ray_caster
        if choice not in RAY_CASTERS:
            raise EnvError(f"ray_caster {choice!r}: expected one of {', '.join(RAY_CASTERS)}")
        if choice == "prism":
            if not self.config.lidar3d.level:
                raise EnvError("ray_caster 'prism' casts level LiDARs only: the 3D LiDAR's mount has roll or pitch")
            return PrismRayCaster(self.world)
        if choice == "bullet":
            assert self.scene is not None
            return BulletRayCaster(self.scene.client, self.scene.body_classes)
        return EmbreeRayCaster(self.world)

    def _uses_bullet(self) -> bool:
        return self.config.ray_caster == "bullet"

    def _with_movers(
        self,
        origin: np.ndarray,
        azimuths: np.ndarray,
        elevations: np.ndarray,
        ranges: np.ndarray,
        labels: np.ndarray,
        max_range: float,
    ) -> tuple[np.ndarray, np.ndarray]:
        """The static world's ranges and labels (flattened), with the nearer hits on walkers and furniture."""
        ranges, labels = ranges.reshape(-1), labels.reshape(-1)
        if self.movers is None:
            return ranges, labels
        from pimm_env.sim.raycast import _directions

        directions = _directions(azimuths, elevations).reshape(-1, 3)
        return self.movers.occlude(origin, directions, ranges, labels, max_range, self.world.floor_z)

    def _cast_3d(self, x: float, y: float, theta: float) -> tuple[np.ndarray, np.ndarray]:
        """The 3D LiDAR's ranges and labels (flattened, in the order of ``_directions3d``) from its mount on the
        robot at (x, y, theta): a grid of azimuths and elevations for a level mount, rotated rays otherwise."""
        l3 = self.config.lidar3d
        c, s = np.cos(theta), np.sin(theta)
        origin = np.array([x + c * l3.mount_x - s * l3.mount_y, y + s * l3.mount_x + c * l3.mount_y, 0.0])
        origin[2] = self.world.floor_z + l3.height
        if l3.level:
            azimuths = self._azimuths3d + (theta + np.radians(l3.mount_yaw_deg))
            ranges, labels = self.caster.cast(origin, azimuths, self._elevations, l3.max_range)
            return self._with_movers(origin, azimuths, self._elevations, ranges, labels, l3.max_range)
        turn = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]) @ mount_rotation(l3)
        directions = self._directions3d @ turn.T
        ranges, labels = self.caster.cast_directions(origin, directions, l3.max_range)  # type: ignore[attr-defined]
        if self.movers is None:
            return ranges, labels
        return self.movers.occlude(origin, directions, ranges, labels, l3.max_range, self.world.floor_z)

    def cast_sensor_rays(self, directions: np.ndarray, mount: Lidar3DConfig) -> tuple[np.ndarray, np.ndarray]:
        """Ranges (``inf``: no return within ``mount.max_range``) and labels of rays along ``directions`` (N, 3,
        unit, the sensor's frame) from a sensor mounted as ``mount`` on the robot at its current pose, walkers
        and unmapped furniture included: a scan of any LiDAR layout or pattern (training data for other
        sensors). No noise is added."""
        if not hasattr(self.caster, "cast_directions"):
            raise EnvError(f"ray caster {self.config.ray_caster!r} casts no arbitrary rays; use embree or bullet")
        origin, world_directions = self._sensor_rays(directions, mount)
        ranges, labels = self.caster.cast_directions(origin, world_directions, mount.max_range)  # type: ignore[attr-defined]
        if self.movers is None:
            return ranges, labels
        return self.movers.occlude(origin, world_directions, ranges, labels, mount.max_range, self.world.floor_z)

    def sensor_ray_elements(self, directions: np.ndarray, mount: Lidar3DConfig) -> np.ndarray:
        """Which of the world's elements (index into ``world.elements``; -1: none within ``mount.max_range``)
        each ray of ``cast_sensor_rays`` hits first, walkers left out: what a segmentation error lies on."""
        if not hasattr(self.caster, "cast_elements"):
            raise EnvError(f"ray caster {self.config.ray_caster!r} does not name the elements it hits; use embree")
        origin, world_directions = self._sensor_rays(directions, mount)
        return self.caster.cast_elements(origin, world_directions, mount.max_range)  # type: ignore[attr-defined]

    def _sensor_rays(self, directions: np.ndarray, mount: Lidar3DConfig) -> tuple[np.ndarray, np.ndarray]:
        """The sensor's origin and ``directions`` (its frame) in the world frame, mounted as ``mount``."""
        x, y, theta = self.robot.pose
        c, s = np.cos(theta), np.sin(theta)
        origin = np.array([x + c * mount.mount_x - s * mount.mount_y, y + s * mount.mount_x + c * mount.mount_y, 0.0])
        origin[2] = self.world.floor_z + mount.height
        turn = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]) @ mount_rotation(mount)
        return origin, np.asarray(directions, dtype=float) @ turn.T

    def _sense(self) -> None:
        """Take the scans that are due at the current time."""
        assert self._noise is not None, "reset() first"
        noise3d, noise2d = self._noise
        l3, l2 = self.config.lidar3d, self.config.lidar2d
        x, y, theta = self.robot.pose
        fresh_cloud = fresh_scan = False
        eps = 1e-9
        if l3.enabled and self._time + eps >= self._next_cloud:
            ranges, labels = self._cast_3d(x, y, theta)
            hit = np.isfinite(ranges)
            noisy = noisy_ranges(
                np.where(hit, ranges, 0) / l3.max_range, hit, l3.max_range, l3.min_range, l3.noise_std, noise3d
            )
            returned = hit & (noisy < l3.max_range)
            self._cloud = np.where(returned[:, None], self._directions3d * noisy[:, None], 0.0).astype(np.float32)
            self._cloud_mask = returned.astype(np.int8)
            self._labels = np.where(returned, labels, -1).astype(np.int8)
            self._cloud_time = self._time
            self._next_cloud = self._next_cloud + 1.0 / l3.rate_hz
            fresh_cloud = True
        if l2.enabled and self._time + eps >= self._next_scan:
            c, s = np.cos(theta), np.sin(theta)
            mx, my = x + c * l2.mount_x - s * l2.mount_y, y + s * l2.mount_x + c * l2.mount_y
            origin = np.array([mx, my, self.world.floor_z + l2.height])
            ranges, labels2d = self.caster.cast(origin, self._azimuths2d + theta, np.zeros(1), l2.max_range)
            ranges, _ = self._with_movers(origin, self._azimuths2d + theta, np.zeros(1), ranges, labels2d, l2.max_range)
            hit = np.isfinite(ranges)
            scan = noisy_ranges(
                np.where(hit, ranges, 0) / l2.max_range, hit, l2.max_range, l2.min_range, l2.noise_std, noise2d
            )
            self._scan = scan.astype(np.float32)
            self._scan_time = self._time
            self._next_scan = self._next_scan + 1.0 / l2.rate_hz
            fresh_scan = True
        self._fresh = (fresh_cloud, fresh_scan)
