"""Named LiDAR layouts, shared by the simulator, the localizers and the bag tools.

``--sensors thesis`` is the thesis's pair (a 40 x 360 3D LiDAR over 120 deg, a 360-beam 2D LiDAR); a 2D
preset's name swaps the 2D LiDAR and keeps the thesis's 3D one (``--sensors hokuyo-utm30lx``); names join
with commas. Geometry, range and rate come from the makers' datasheets; the range noise is the simulator's
0.01 m for all of them.

An entry may also be a sensors file (``.yaml``): ``lidar3d:`` and/or ``lidar2d:`` sections whose keys are
``Lidar3DConfig`` / ``Lidar2DConfig`` fields, applied over what the names before it gave. ``replay`` writes one
when it reads a bag's layout from its messages; a user writes one for a LiDAR with no preset.
"""

from __future__ import annotations

from dataclasses import asdict, replace
from pathlib import Path

import numpy as np

from pimm_env.errors import EnvError
from pimm_env.settings import apply_params
from pimm_env.sim.lidar import Lidar2DConfig, Lidar3DConfig, directions_3d, non_repetitive_directions

SENSORS_FILE_SUFFIXES = (".yaml", ".yml")

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
    # Ouster OS0-64: 64 rings over 90 deg (+-45), 1024 columns, 35 m, 10 Hz.
    "os0-64": Lidar3DConfig(layers=64, points_per_layer=1024, vertical_fov_deg=90.0, max_range=35.0),
    # Velodyne VLP-16: 16 rings over 30 deg (+-15), 0.2 deg at 10 Hz (1 800 columns), 100 m.
    "vlp-16": Lidar3DConfig(layers=16, points_per_layer=1800, vertical_fov_deg=30.0, max_range=100.0),
    # Ouster OS1-128: 128 rings over 45 deg (+-22.5), 1024 columns, 90 m (at 10 % reflectivity: 45 m).
    "os1-128": Lidar3DConfig(layers=128, points_per_layer=1024, vertical_fov_deg=45.0, max_range=90.0),
}


#: a non-repetitive pattern (Mid-360-like: ``lidar.non_repetitive_directions``), named beside the spinning presets
NON_REPETITIVE = "mid-360"


def scan_layout(name: str) -> Lidar3DConfig:
    """The 3D LiDAR a layout name stands for: a spinning preset, or the non-repetitive pattern's range (40 m)."""
    if name == NON_REPETITIVE:
        return replace(LIDAR_3D["thesis"], max_range=40.0)
    if name not in LIDAR_3D:
        raise EnvError(f"unknown 3D layout {name!r}; valid: {', '.join([*LIDAR_3D, NON_REPETITIVE])}")
    return LIDAR_3D[name]


def scan_directions(name: str, mount: Lidar3DConfig, rng: np.random.Generator, rays: int = 20_000) -> np.ndarray:
    """Unit ray directions (sensor frame) of one scan of layout ``name``: the preset's grid, or ``rays`` fresh
    rays of the non-repetitive pattern."""
    return non_repetitive_directions(rays, rng) if name == NON_REPETITIVE else directions_3d(mount)


def sensor_layouts(spec: str | None) -> tuple[Lidar3DConfig, Lidar2DConfig]:
    """The 3D and 2D LiDARs that ``spec`` (preset names, comma-separated; None: ``thesis``) names."""
    lidar3d, lidar2d = LIDAR_3D["thesis"], LIDAR_2D["thesis"]
    for name in (spec or "thesis").split(","):
        name = name.strip()
        if name.endswith(SENSORS_FILE_SUFFIXES):
            lidar3d, lidar2d = read_sensors_file(Path(name), lidar3d, lidar2d)
            continue
        if name not in LIDAR_2D and name not in LIDAR_3D:
            valid = sorted(set(LIDAR_2D) | set(LIDAR_3D))
            raise EnvError(f"unknown sensor preset {name!r}; valid: {', '.join(valid)}, or a sensors .yaml file")
        lidar3d = LIDAR_3D.get(name, lidar3d)
        lidar2d = LIDAR_2D.get(name, lidar2d)
    return lidar3d, lidar2d


def read_sensors_file(
    path: Path, lidar3d: Lidar3DConfig = LIDAR_3D["thesis"], lidar2d: Lidar2DConfig = LIDAR_2D["thesis"]
) -> tuple[Lidar3DConfig, Lidar2DConfig]:
    """``lidar3d`` and ``lidar2d`` with the sections of the sensors file at ``path`` applied; errors name the
    file and the section or field."""
    import yaml

    try:
        data = yaml.safe_load(Path(path).read_text())
    except OSError as error:
        raise EnvError(f"{path}: cannot read the sensors file ({error.strerror})") from None
    except yaml.YAMLError as error:
        raise EnvError(f"{path}: not YAML ({error})") from None
    if not isinstance(data, dict) or not set(data) <= {"lidar3d", "lidar2d"} or not data:
        raise EnvError(f"{path}: a sensors file holds a lidar3d and/or a lidar2d section, got {data!r}")
    return (
        apply_params(lidar3d, data.get("lidar3d", {}), f"{path}: lidar3d"),
        apply_params(lidar2d, data.get("lidar2d", {}), f"{path}: lidar2d"),
    )


def write_sensors_file(
    path: Path, lidar3d: Lidar3DConfig | None, lidar2d: Lidar2DConfig | None, note: str = ""
) -> Path:
    """A sensors file with the given sections (``sensor_layouts`` reads it back to the same configs)."""
    import yaml

    data = {k: asdict(v) for k, v in (("lidar3d", lidar3d), ("lidar2d", lidar2d)) if v is not None}
    header = "".join(f"# {line}\n" for line in note.splitlines())
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    Path(path).write_text(header + yaml.safe_dump(data, sort_keys=False))
    return Path(path)
