"""Named LiDAR layouts, shared by the simulator, the localizers and the bag tools.

``--sensors thesis`` is the thesis's pair (a 40 x 360 3D LiDAR over 120 deg, a 360-beam 2D LiDAR); a 2D
preset's name swaps the 2D LiDAR and keeps the thesis's 3D one (``--sensors hokuyo-utm30lx``); names join
with commas. Geometry, range and rate come from the makers' datasheets; the range noise is the simulator's
0.01 m for all of them.
"""

from __future__ import annotations

from pimm_env.sim.lidar import Lidar2DConfig, Lidar3DConfig

LIDAR_2D: dict[str, Lidar2DConfig] = {
    "thesis": Lidar2DConfig(),
    # Hokuyo UTM-30LX: 270 deg at 0.25 deg (1081 steps), 0.1-30 m, 25 ms per scan.
    "hokuyo-utm30lx": Lidar2DConfig(
        beams=1081, angle_min_deg=-135.0, angle_max_deg=135.0, min_range=0.1, max_range=30.0, rate_hz=40.0
    ),
    # SICK LMS200: 180 deg at 1 deg (181 beams), up to 80 m, 75 Hz at that resolution.
    "sick-lms200": Lidar2DConfig(
        beams=181, angle_min_deg=-90.0, angle_max_deg=90.0, min_range=0.05, max_range=80.0, rate_hz=75.0
    ),
}
LIDAR_3D: dict[str, Lidar3DConfig] = {
    "thesis": Lidar3DConfig(),
    # Ouster OS0-64: 64 rings over 90 deg (+-45), 1024 columns, 35 m (as issue 16 gives it), 10 Hz.
    "os0-64": Lidar3DConfig(layers=64, points_per_layer=1024, vertical_fov_deg=90.0, max_range=35.0),
    # Velodyne VLP-16: 16 rings over 30 deg (+-15), 0.2 deg at 10 Hz (1 800 columns), 100 m.
    "vlp-16": Lidar3DConfig(layers=16, points_per_layer=1800, vertical_fov_deg=30.0, max_range=100.0),
}


def sensor_layouts(spec: str | None) -> tuple[Lidar3DConfig, Lidar2DConfig]:
    """The 3D and 2D LiDARs that ``spec`` (preset names, comma-separated; None: ``thesis``) names."""
    lidar3d, lidar2d = LIDAR_3D["thesis"], LIDAR_2D["thesis"]
    for name in (spec or "thesis").split(","):
        name = name.strip()
        if name not in LIDAR_2D and name not in LIDAR_3D:
            valid = sorted(set(LIDAR_2D) | set(LIDAR_3D))
            raise ValueError(f"unknown sensor preset {name!r}; valid: {', '.join(valid)}")
        lidar3d = LIDAR_3D.get(name, lidar3d)
        lidar2d = LIDAR_2D.get(name, lidar2d)
    return lidar3d, lidar2d
