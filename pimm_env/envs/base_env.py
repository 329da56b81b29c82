"""The simulator behind PIMM's environments: a world, a diff-drive robot, wheel odometry and two LiDARs.

Concrete environments (see :mod:`pimm_env.envs.iilab_env`) choose the world and add reward and info hooks.
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
from scipy import ndimage

from pimm_env.envs.env_spaces import MAX_ODOM, action_space, observation_space
from pimm_env.envs.sim_config import RAY_CASTERS, SimConfig
from pimm_env.errors import EnvError, WorldError
from pimm_env.geometry import wrap_angle
from pimm_env.mapping.derived_maps import DerivedMaps, load_derived_maps
from pimm_env.mapping.occupancy import body_obstacles
from pimm_env.sim.lidar import (
    Lidar3DConfig,
    azimuths_3d,
    beam_bearings_2d,
    directions_3d,
    elevations_3d,
    mount_rotation,
    noisy_ranges,
)
from pimm_env.sim.raycast import BulletRayCaster, EmbreeRayCaster, PrismRayCaster, RayCaster
from pimm_env.sim.robot import DiffDriveRobot
from pimm_env.sim.scene import BulletScene
from pimm_env.world.files import World, load_world

RESET_OPTIONS = frozenset({"pose", "kidnap"})


class LidarRobotEnv(gym.Env):
    """Base simulator; see :class:`pimm_env.envs.iilab_env.IILabEnv` for the documented environment."""

    metadata = {"render_modes": ["rgb_array"], "render_fps": 10}

    def __init__(
        self, world: str | World = "iilab", config: SimConfig | None = None, render_mode: str | None = None
    ) -> None:
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise EnvError(f"render_mode {render_mode!r} is not supported; use one of {self.metadata['render_modes']}")
        self.render_mode = render_mode
        self.config = config or SimConfig()
        self._world_arg = world
        self.world = world if isinstance(world, World) else load_world(world)
        self.maps: DerivedMaps = load_derived_maps(self.world)
        #: pybullet's scene of the world, built only for the ``bullet`` ray caster (the others read the world)
        self.scene = BulletScene(self.world, self.config.robot.footprint_radius) if self._uses_bullet() else None
        #: one frame per control step
        self.metadata = {**type(self).metadata, "render_fps": round(1.0 / self.config.robot.control_dt)}
        self.caster = self._make_caster()
        self._collision_clearance, self._start_cells = self._clearance_maps()
        self.robot = DiffDriveRobot(self.config.robot)

        l3, l2 = self.config.lidar3d, self.config.lidar2d
        self._elevations = elevations_3d(l3)
        self._azimuths3d = azimuths_3d(l3)
        self._azimuths2d = beam_bearings_2d(l2)
        self._directions3d = directions_3d(l3)  # sensor frame, same order as the cast
        n = l3.num_points
        self.action_space = action_space(self.config)
        self.observation_space = observation_space(self.config)
        self.movers: Any = None  # sim.movers.Movers while the config asks for walkers or unmapped furniture
        self._time = 0.0
        self._next_cloud = 0.0
        self._next_scan = 0.0
        self._cloud = np.zeros((n, 3), dtype=np.float32)
        self._cloud_mask = np.zeros(n, dtype=np.int8)
        self._labels = np.full(n, -1, dtype=np.int8)
        self._scan = np.full(l2.beams, l2.max_range, dtype=np.float32)
        self._cloud_time = 0.0
        self._scan_time = 0.0
        self._collided = False
        self._fresh = (False, False)
        self._noise: tuple[np.random.Generator, np.random.Generator] | None = None  # 3D, 2D LiDAR

    # ------------------------------------------------------------------ set-up helpers
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

    def _place_body(self) -> None:
        if self.scene is not None:
            self.scene.place_robot(self.robot.pose)

    def _clearance_maps(self) -> tuple[np.ndarray, np.ndarray]:
        """Distance to anything the robot's body could touch, and the cells where a random start may be."""
        grid = self.maps.occupancy.grid
        body = body_obstacles(self.world, grid)
        clearance = ndimage.distance_transform_edt(~body) * grid.resolution
        radius = self.config.robot.footprint_radius
        start = self.maps.occupancy.free & (clearance >= radius + self.config.start_clearance)
        return clearance, np.argwhere(start)

    def clearance_at(self, x: float, y: float) -> float:
        """Distance (m) from (x, y) to the nearest obstacle at body height; 0 outside the map."""
        rows, cols, valid = self.maps.occupancy.grid.cells_of(np.array([[x, y]]))
        if not valid[0]:
            return 0.0
        return float(self._collision_clearance[rows[0], cols[0]])

    def start_positions(self, spacing: float) -> np.ndarray:
        """(x, y) of a square grid with ``spacing`` (m) over the cells where a random start may be."""
        if spacing <= 0:
            raise EnvError(f"grid spacing must be positive, got {spacing}")
        grid = self.maps.occupancy.grid
        allowed = grid.empty_mask()
        allowed[tuple(self._start_cells.T)] = True
        step = max(1, round(spacing / grid.resolution))
        rows, cols = np.nonzero(allowed[::step, ::step])
        x = grid.origin[0] + (cols * step + 0.5) * grid.resolution
        y = grid.origin[1] + (rows * step + 0.5) * grid.resolution
        return np.column_stack([x, y])

    @property
    def sim_time(self) -> float:
        """Simulated time since the last full reset (s); a kidnap does not reset it."""
        return self._time

    def _blocked(self, x: float, y: float) -> bool:
        return self.clearance_at(x, y) < self.config.robot.footprint_radius

    # ------------------------------------------------------------------ gymnasium API
    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        super().reset(seed=seed)
        options = dict(options or {})
        unknown = set(options) - RESET_OPTIONS
        if unknown:
            raise EnvError(f"unknown reset option(s) {sorted(unknown)}; valid: {sorted(RESET_OPTIONS)}")
        if "pose" in options and "kidnap" in options:
            raise EnvError("reset options 'pose' and 'kidnap' exclude each other")
        kidnap = options.get("kidnap", False)
        kidnapped = kidnap is not False and kidnap is not None
        if not kidnapped or self._noise is None:
            # Each LiDAR draws its noise from its own stream, so that switching one off (nobody reads it)
            # leaves the motion, odometry and the other LiDAR exactly as they were.
            lidar3d, lidar2d = self.np_random.spawn(2)
            self._noise = (lidar3d, lidar2d)
        if kidnapped:
            pose = self._random_pose() if kidnap is True else self._checked_pose(kidnap, "kidnap")
            self.robot.teleport(pose)
        else:
            self._place_movers()
            pose = (
                self._checked_pose(options["pose"], "pose") if options.get("pose") is not None else self._random_pose()
            )
            self.robot.reset(pose, self.np_random)
            self._time = 0.0
            self._next_cloud = self._next_scan = 0.0
        self._collided = False
        self._place_body()
        self._sense()
        return self._observation(), self._info()

    def step(self, action):
        action = np.asarray(action, dtype=float)
        if action.shape != (2,):
            raise EnvError(f"action must have shape (2,) [linear m/s, angular rad/s], got shape {action.shape}")
        if not np.all(np.isfinite(action)):
            raise EnvError(f"action must be finite, got {action.tolist()}")
        action = np.clip(action, self.action_space.low, self.action_space.high)
        self._collided = self.robot.step(float(action[0]), float(action[1]), self.np_random, self._blocked)
        self._time += self.config.robot.control_dt
        if self.movers is not None:
            self.movers.step(self.config.robot.control_dt, self.robot.pose[:2])
        self._place_body()
        self._sense()
        obs = self._observation()
        info = self._info()
        return obs, float(self._reward(info)), bool(self._terminated(info)), False, info

    def render(self):
        if self.render_mode != "rgb_array":
            return None
        from pimm_env.envs.render import draw_top_down

        return draw_top_down(
            self.maps.occupancy,
            self.robot.pose,
            self._cloud,
            self._labels,
            self._scan,
            self._azimuths2d,
            self.config.lidar2d.max_range,
            self.config.robot.footprint_radius,
            None if self.movers is None or (boxes := self.movers.boxes()) is None else boxes.as_array(),
        )

    def close(self) -> None:
        scene = getattr(self, "scene", None)  # close() may run on an env whose __init__ failed
        if scene is not None:
            scene.close()

    # ------------------------------------------------------------------ hooks for concrete envs
    def _reward(self, info: dict[str, Any]) -> float:
        return 0.0

    def _terminated(self, info: dict[str, Any]) -> bool:
        return False

    # ------------------------------------------------------------------ internals
    def _random_pose(self) -> np.ndarray:
        if len(self._start_cells) == 0:
            raise WorldError(f"world {self.world.name!r} has no free cell wide enough for the robot")
        grid = self.maps.occupancy.grid
        row, col = self._start_cells[self.np_random.integers(len(self._start_cells))]
        jitter = self.np_random.uniform(-0.5, 0.5, size=2) * grid.resolution
        x = grid.origin[0] + (col + 0.5) * grid.resolution + jitter[0]
        y = grid.origin[1] + (row + 0.5) * grid.resolution + jitter[1]
        return np.array([x, y, self.np_random.uniform(-np.pi, np.pi)])

    def _checked_pose(self, pose: Any, name: str) -> np.ndarray:
        try:
            arr = np.asarray(pose, dtype=float).reshape(-1)
        except (TypeError, ValueError):
            raise EnvError(f"reset option {name!r} must be [x, y, theta], got {pose!r}") from None
        if arr.shape != (3,) or not np.all(np.isfinite(arr)):
            raise EnvError(f"reset option {name!r} must be three finite numbers [x, y, theta], got {pose!r}")
        x, y = arr[0], arr[1]
        rows, cols, valid = self.maps.occupancy.grid.cells_of(arr[None, :2])
        if not valid[0] or (not self.maps.occupancy.free[rows[0], cols[0]] and self.world.area_of(x, y) is None):
            raise EnvError(f"reset option {name!r}: ({x:.2f}, {y:.2f}) is outside the map of {self.world.name!r}")
        if self._blocked(x, y):
            raise EnvError(
                f"reset option {name!r}: ({x:.2f}, {y:.2f}) is inside an obstacle "
                f"(clearance {self.clearance_at(x, y):.2f} m < robot radius {self.config.robot.footprint_radius} m)"
            )
        arr[2] = wrap_angle(arr[2])
        return arr

    def _place_movers(self) -> None:
        """This episode's walkers and unmapped furniture, from a stream of their own (the robot's and the
        LiDARs' draws stay as they are without them)."""
        from pimm_env.sim.movers import Movers

        c = self.config
        self.movers = None
        if c.walkers or c.unmapped:
            self.movers = Movers(self.maps.occupancy, c.walkers, c.unmapped, self.np_random.spawn(1)[0])

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

    def _observation(self) -> dict[str, np.ndarray]:
        odom = self.robot.odom
        return {
            "odom": np.array(
                [
                    np.clip(odom[0], -MAX_ODOM, MAX_ODOM),
                    np.clip(odom[1], -MAX_ODOM, MAX_ODOM),
                    np.clip(odom[2], -np.pi, np.pi),
                ],
                dtype=np.float32,
            ),
            "cloud": self._cloud.copy(),
            "cloud_mask": self._cloud_mask.copy(),
            "scan": self._scan.copy(),
            "time": np.array([self._time]),
            "cloud_time": np.array([self._cloud_time]),
            "scan_time": np.array([self._scan_time]),
        }

    def _info(self) -> dict[str, Any]:
        return {
            "true_pose": self.robot.pose.copy(),
            "labels": self._labels.copy(),
            "collision": bool(self._collided),
            "fresh_cloud": self._fresh[0],
            "fresh_scan": self._fresh[1],
            "area": self.world.area_of(*self.robot.pose[:2]),
            "travelled": self.robot.travelled,
            **(self.movers.info() if self.movers is not None else {}),
        }

    # ------------------------------------------------------------------ pickling
    def __getstate__(self) -> dict[str, Any]:
        """The constructor's arguments (world, the whole ``SimConfig``, render mode) and the state that changes:
        the robot, the clock, scans, noise streams, movers; the rest is rebuilt from the world on unpickling."""
        rebuilt = {"_world_arg", "_collision_clearance", "_start_cells", "_elevations", "_azimuths3d", "_azimuths2d"}
        rebuilt.add("_directions3d")
        dynamic = {k: v for k, v in self.__dict__.items() if k.startswith("_") and k not in rebuilt}
        return {
            "world": self._world_arg,
            "config": self.config,
            "render_mode": self.render_mode,
            "robot": self.robot.__dict__.copy(),
            "movers": self.movers,
            "dynamic": dynamic,
        }

    def __setstate__(self, state: dict[str, Any]) -> None:
        LidarRobotEnv.__init__(self, state["world"], state["config"], state["render_mode"])
        self.robot.__dict__.update(state["robot"])
        self.movers = state["movers"]
        self.__dict__.update(state["dynamic"])
        self._place_body()
