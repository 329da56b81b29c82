"""What defines a simulation besides its world: the robot, the two LiDARs, the ray caster and the movers."""

from __future__ import annotations

from dataclasses import dataclass, field, replace

from pimm_env.sim.lidar import Lidar2DConfig, Lidar3DConfig
from pimm_env.sim.robot import RobotConfig

RAY_CASTERS = ("auto", "prism", "embree", "bullet")


@dataclass(frozen=True)
class SimConfig:
    """Everything that defines a simulation besides the world."""

    robot: RobotConfig = field(default_factory=RobotConfig)
    lidar3d: Lidar3DConfig = field(default_factory=Lidar3DConfig)
    lidar2d: Lidar2DConfig = field(default_factory=Lidar2DConfig)
    start_clearance: float = 0.15  # extra free space around random start poses (m)
    #: "auto" (= "embree": Open3D's Embree scene, any world, 3-4 ms per 3D scan whatever the element count),
    #: "prism" (exact, boxes and cylinders only, its cost grows with the elements) or "bullet" (slowest)
    ray_caster: str = "auto"
    #: people walking about and furniture that the derived maps do not have (``sim/movers.py``), drawn per
    #: episode from the reset's seed; seen by both LiDARs as clutter, reported in ``info``
    walkers: int = 0
    unmapped: int = 0


def with_sensors(config: SimConfig, spec: str | None) -> SimConfig:
    """``config`` with the LiDARs that ``spec`` names (``sim/sensors.py``'s presets; their ``enabled`` flags
    kept)."""
    from pimm_env.sim.sensors import sensor_layouts

    lidar3d, lidar2d = sensor_layouts(spec)
    return replace(
        config,
        lidar3d=replace(lidar3d, enabled=config.lidar3d.enabled),
        lidar2d=replace(lidar2d, enabled=config.lidar2d.enabled),
    )
