"""The 3D and 2D LiDARs: ray patterns, batched ray casting in pybullet, range noise and labels."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pimm_env.errors import EnvError

#: pybullet's rayTestBatch takes at most 16384 rays and drops one at exactly that count.
MAX_RAYS_PER_BATCH = 8192


@dataclass(frozen=True)
class Lidar3DConfig:
    """Defaults: the thesis's 3D LiDAR, 40 layers x 360 points over 360 x 120 deg, 10 m range."""

    layers: int = 40
    points_per_layer: int = 360
    vertical_fov_deg: float = 120.0
    max_range: float = 10.0
    min_range: float = 0.05
    noise_std: float = 0.01
    rate_hz: float = 10.0
    height: float = 0.50  # above the floor: the mount's z
    enabled: bool = True  # off: no rays are cast, the cloud stays empty (for localizers that do not read it)
    #: The rest of the mount pose in the robot's frame (the thesis's LiDAR: centred and level): position (m)
    #: and roll, pitch, yaw (deg, applied as R = Rz(yaw) Ry(pitch) Rx(roll), as a URDF joint's rpy).
    mount_x: float = 0.0
    mount_y: float = 0.0
    mount_roll_deg: float = 0.0
    mount_pitch_deg: float = 0.0
    mount_yaw_deg: float = 0.0

    @property
    def num_points(self) -> int:
        return self.layers * self.points_per_layer

    @property
    def mount(self) -> tuple[float, float, float, float, float, float]:
        """(x, y, z, roll, pitch, yaw): m and deg, in the robot's frame, z above the floor."""
        return (self.mount_x, self.mount_y, self.height, self.mount_roll_deg, self.mount_pitch_deg, self.mount_yaw_deg)

    @property
    def level(self) -> bool:
        """True when the sensor's rays are a grid of azimuths and elevations in the robot's frame."""
        return self.mount_roll_deg == 0.0 and self.mount_pitch_deg == 0.0


@dataclass(frozen=True)
class Lidar2DConfig:
    """Defaults: the thesis's 2D LiDAR, 360 beams over 360 deg from -180 deg, 10 m range, at the robot's centre.

    Beams run counter-clockwise from ``angle_min_deg`` to ``angle_max_deg`` (both included, as a LaserScan's
    angle_min/angle_max; a full circle leaves out the end, which is the start). The sensor sits at
    (``mount_x``, ``mount_y``) in the robot's frame, turned by ``mount_yaw_deg``.
    """

    beams: int = 360
    max_range: float = 10.0
    min_range: float = 0.05
    noise_std: float = 0.01
    rate_hz: float = 10.0
    height: float = 0.30  # above the floor; the occupancy grid is cut at this height
    enabled: bool = True  # off: no rays are cast, every beam reads max_range
    angle_min_deg: float = -180.0
    angle_max_deg: float = 180.0
    mount_x: float = 0.0
    mount_y: float = 0.0
    mount_yaw_deg: float = 0.0

    def __post_init__(self) -> None:
        if self.beams < 1 or not self.angle_min_deg < self.angle_max_deg <= self.angle_min_deg + 360.0:
            raise EnvError(
                f"2D LiDAR: need beams >= 1 and angle_min_deg < angle_max_deg <= angle_min_deg + 360, got "
                f"{self.beams} beams over [{self.angle_min_deg}, {self.angle_max_deg}] deg"
            )
        if not 0 <= self.min_range < self.max_range:
            raise EnvError(f"2D LiDAR: need 0 <= min_range < max_range, got {self.min_range}, {self.max_range}")


def elevations_3d(config: Lidar3DConfig) -> np.ndarray:
    """Elevation of each layer (rad), lowest first, evenly over the vertical field of view."""
    half = np.radians(config.vertical_fov_deg) / 2
    return np.linspace(-half, half, config.layers)


def azimuths_3d(config: Lidar3DConfig) -> np.ndarray:
    """Azimuth of each point of a layer (rad) in the sensor frame, from -pi counter-clockwise."""
    return -np.pi + 2 * np.pi * np.arange(config.points_per_layer) / config.points_per_layer


def directions_3d(config: Lidar3DConfig) -> np.ndarray:
    """Unit ray directions in the sensor frame, (layers * points, 3), layer by layer from the lowest."""
    el, az = np.meshgrid(elevations_3d(config), azimuths_3d(config), indexing="ij")
    return np.stack([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)], axis=-1).reshape(-1, 3)


def beam_angles_2d(config: Lidar2DConfig) -> np.ndarray:
    """Beam angles in the sensor frame, counter-clockwise from ``angle_min_deg``."""
    low, high = np.radians(config.angle_min_deg), np.radians(config.angle_max_deg)
    if config.angle_max_deg - config.angle_min_deg >= 360.0:  # a full circle: the end is the start
        return low + 2 * np.pi * np.arange(config.beams) / config.beams
    return np.linspace(low, high, config.beams) if config.beams > 1 else np.array([low])


def beam_bearings_2d(config: Lidar2DConfig) -> np.ndarray:
    """Beam angles in the robot's frame (the sensor's mount yaw added)."""
    return beam_angles_2d(config) + np.radians(config.mount_yaw_deg)


def cast_rays(client, origins: np.ndarray, ends: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Hit fraction (1 where nothing was hit) and body id (-1) of each ray from ``origins`` to ``ends``."""
    n = len(origins)
    fractions = np.ones(n)
    bodies = np.full(n, -1, dtype=np.int64)
    for start in range(0, n, MAX_RAYS_PER_BATCH):
        stop = min(n, start + MAX_RAYS_PER_BATCH)
        results = client.rayTestBatch(origins[start:stop].tolist(), ends[start:stop].tolist(), numThreads=0)
        if len(results) != stop - start:
            raise RuntimeError(f"pybullet returned {len(results)} ray results for {stop - start} rays")
        ids, _, frac = zip(*[r[:3] for r in results], strict=True)
        bodies[start:stop] = ids
        fractions[start:stop] = frac
    fractions[bodies < 0] = 1.0
    return fractions, bodies


def noisy_ranges(
    fractions: np.ndarray,
    hit: np.ndarray,
    max_range: float,
    min_range: float,
    noise_std: float,
    rng: np.random.Generator,
) -> np.ndarray:
    """Ranges with Gaussian noise; rays with no return, or closer than ``min_range``, get ``max_range``."""
    ranges = fractions * max_range + noise_std * rng.standard_normal(len(fractions))
    ranges = np.clip(ranges, 0.0, max_range)
    ranges[~hit | (ranges < min_range)] = max_range
    return ranges


def mount_rotation(config: Lidar3DConfig) -> np.ndarray:
    """The 3D LiDAR's orientation in the robot's frame, ``Rz(yaw) Ry(pitch) Rx(roll)`` (3 x 3)."""
    roll, pitch, yaw = np.radians([config.mount_roll_deg, config.mount_pitch_deg, config.mount_yaw_deg])
    cr, sr, cp, sp, cy, sy = np.cos(roll), np.sin(roll), np.cos(pitch), np.sin(pitch), np.cos(yaw), np.sin(yaw)
    rx = np.array([[1.0, 0.0, 0.0], [0.0, cr, -sr], [0.0, sr, cr]])
    ry = np.array([[cp, 0.0, sp], [0.0, 1.0, 0.0], [-sp, 0.0, cp]])
    rz = np.array([[cy, -sy, 0.0], [sy, cy, 0.0], [0.0, 0.0, 1.0]])
    return rz @ ry @ rx


def to_robot_frame(points: np.ndarray, config: Lidar3DConfig) -> np.ndarray:
    """Sensor-frame points in the robot's frame at the sensor's height: turned by the mount's roll, pitch and
    yaw and moved by its x and y, with z still measured from the sensor (as a level, centred sensor gives it,
    and as the thesis's network reads it). The points themselves for the thesis's mount."""
    if config.mount == (0.0, 0.0, config.height, 0.0, 0.0, 0.0):
        return points
    turned = points @ mount_rotation(config).T.astype(points.dtype)
    turned[:, 0] += config.mount_x
    turned[:, 1] += config.mount_y
    return turned


def non_repetitive_directions(count: int, rng: np.random.Generator) -> np.ndarray:
    """A Mid-360-like scan: ``count`` rays over 360 deg of azimuth and -7..52 deg of elevation, a new
    quasi-random (Halton 2, 3) set each scan, as a non-repetitive pattern never repeats its rays."""
    start = int(rng.integers(0, 1 << 20))
    index = np.arange(start, start + count)
    azimuth = 2 * np.pi * _halton(index, 2) - np.pi
    low, high = np.sin(np.radians(-7.0)), np.sin(np.radians(52.0))
    elevation = np.arcsin(low + (high - low) * _halton(index, 3))  # even over the sphere's band
    return np.column_stack(
        [np.cos(elevation) * np.cos(azimuth), np.cos(elevation) * np.sin(azimuth), np.sin(elevation)]
    )


def _halton(index: np.ndarray, base: int) -> np.ndarray:
    result = np.zeros(len(index))
    fraction = 1.0 / base
    i = index.copy()
    while np.any(i > 0):
        result += fraction * (i % base)
        i //= base
        fraction /= base
    return result
