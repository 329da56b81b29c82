"""The simulator behind PIMM's environments: a world, a diff-drive robot, wheel odometry and two LiDARs.

Concrete environments (see :mod:`pimm_env.envs.iilab_env`) choose the world and add reward and info hooks.
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
from scipy import ndimage

from pimm_env.envs.env_spaces import MAX_ODOM, action_space, observation_space
from pimm_env.envs.sensing import LidarSensing
from pimm_env.envs.sim_config import SimConfig
from pimm_env.errors import EnvError, WorldError
from pimm_env.geometry import wrap_angle
from pimm_env.mapping.derived_maps import DerivedMaps, load_derived_maps
from pimm_env.mapping.occupancy import body_obstacles
from pimm_env.sim.lidar import (
    azimuths_3d,
    beam_bearings_2d,
    directions_3d,
    elevations_3d,
)
from pimm_env.sim.robot import DiffDriveRobot
from pimm_env.sim.scene import BulletScene
from pimm_env.world.files import World, load_world

RESET_OPTIONS = frozenset({"pose", "kidnap"})


class LidarRobotEnv(LidarSensing, gym.Env):
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

        boxes = None if self.movers is None else self.movers.boxes()
        scan = (self._scan, self._azimuths2d, self.config.lidar2d.max_range, self.config.robot.footprint_radius)
        drawn = (self.maps.occupancy, self.robot.pose, self._cloud, self._labels, *scan)
        return draw_top_down(*drawn, None if boxes is None else boxes.as_array())

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
        rebuilt = {"_world_arg", "_collision_clearance", "_start_cells", "_elevations", "_azimuths3d", "_azimuths2d",
                   "_directions3d"}  # fmt: skip
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
