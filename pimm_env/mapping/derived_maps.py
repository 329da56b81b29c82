"""Maps derived from a world, stored next to it: occupancy grid and corner map.

Each map records a hash of the world file and of the settings that made it. Reading them
(:func:`load_derived_maps`, what the env and the localizers do) never writes: missing or stale maps are an
error that says how to rebuild them. The commands that prepare a world call :func:`ensure_derived_maps`, and
``python -m pimm_env.mapping iilab`` (``make maps``) rebuilds them by hand.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy import ndimage

from pimm_env.errors import StaleMapsError
from pimm_env.mapping.corner_map import CornerMap, CornerMapConfig, derive_corner_map, load_corner_map, save_corner_map
from pimm_env.mapping.map_server import load_map_server
from pimm_env.mapping.occupancy import (
    OccupancyGrid,
    occupancy_from_world,
    resample_occupied,
    save_map_server,
    tolerant_iou,
)
from pimm_env.world.files import World, world_dir

OCCUPANCY_RESOLUTION = 0.05
#: Height of the 2D LiDAR above the floor; the occupancy grid is cut there.
SCAN_HEIGHT = 0.30
_VERSION = "1"


@dataclass(frozen=True)
class DerivedMaps:
    occupancy: OccupancyGrid
    corners: CornerMap


def _stamp(world: World) -> str:
    digest = hashlib.sha256()
    if world.source is not None and Path(world.source).is_file():
        digest.update(Path(world.source).read_bytes())
    digest.update(f"{_VERSION}/{OCCUPANCY_RESOLUTION}/{SCAN_HEIGHT}/{CornerMapConfig()}".encode())
    if world.seen_walls is not None:
        digest.update(np.ascontiguousarray(world.seen_walls).tobytes())
    return digest.hexdigest()[:16]


def build_derived_maps(world: World, out_dir: Path | None = None) -> DerivedMaps:
    """Derive and write ``occupancy.{pgm,yaml}`` and ``corners.yaml`` for ``world``."""
    out_dir = Path(out_dir or world_dir(world))
    out_dir.mkdir(parents=True, exist_ok=True)
    occupancy = occupancy_from_world(world, OCCUPANCY_RESOLUTION, SCAN_HEIGHT)
    corners = derive_corner_map(world)
    stamp = _stamp(world)
    save_map_server(occupancy, out_dir / "occupancy.yaml")
    with (out_dir / "occupancy.yaml").open("a") as handle:
        handle.write(f"# pimm source: {stamp}\n")
    save_corner_map(corners, out_dir / "corners.yaml", world.name, stamp)
    return DerivedMaps(occupancy, corners)


def _paths(world: World) -> tuple[Path, Path]:
    out_dir = world_dir(world)
    return out_dir / "occupancy.yaml", out_dir / "corners.yaml"


def maps_are_fresh(world: World) -> bool:
    """Whether both derived maps exist and were made from this version of the world file and settings."""
    occ_yaml, corners_yaml = _paths(world)
    stamp = _stamp(world)
    return (
        occ_yaml.is_file()
        and corners_yaml.is_file()
        and f"pimm source: {stamp}" in occ_yaml.read_text()
        and f"source: {stamp}" in corners_yaml.read_text()
    )


def load_derived_maps(world: World) -> DerivedMaps:
    """The stored maps of ``world``; never writes. Missing or stale maps raise :class:`StaleMapsError`."""
    occ_yaml, corners_yaml = _paths(world)
    if not maps_are_fresh(world):
        source = world.source or world.name
        raise StaleMapsError(
            f"the derived maps of world {world.name!r} in {occ_yaml.parent} are missing or older than {source}; "
            f"rebuild them with `python -m pimm_env.mapping {source}` (or `make maps`)"
        )
    return DerivedMaps(load_map_server(occ_yaml), load_corner_map(corners_yaml))


def ensure_derived_maps(world: World) -> DerivedMaps:
    """The maps of ``world``, built and written first if missing or stale: the one step that writes them."""
    if not maps_are_fresh(world):
        return build_derived_maps(world)
    return load_derived_maps(world)


def fidelity_iou(ours: OccupancyGrid, reference: OccupancyGrid, tolerance: float = 0.1, band: float = 0.3) -> float:
    """IoU of occupied cells between two maps of one building, on ``ours``'s grid, with ``tolerance`` (m).

    Only structure within ``band`` of free space (in either map) is compared: what a 2D LiDAR can see.
    Hand-made maps such as the thesis's fill the whole exterior as occupied, which would otherwise
    swamp the score.
    """
    grid = ours.grid
    ref_occupied = resample_occupied(reference, grid)
    gx, gy = reference.grid.cell_centers()
    rows, cols, valid = grid.cells_of(np.stack([gx[reference.free], gy[reference.free]], axis=1))
    ref_free = grid.empty_mask()
    ref_free[rows[valid], cols[valid]] = True
    ref_free &= ~ref_occupied
    near_free = ndimage.distance_transform_edt(~(ours.free | ref_free)) * grid.resolution <= band
    cells = round(tolerance / grid.resolution)
    return tolerant_iou(ours.occupied & near_free, ref_occupied & near_free, cells)


def corner_matches(
    ours: CornerMap, reference: CornerMap, max_dist: float = 0.3, max_angle_deg: float = 20.0
) -> list[tuple[float, float] | None]:
    """For each reference corner, (distance m, angle error deg) of the nearest matching derived corner."""
    out: list[tuple[float, float] | None] = []
    for xy, theta in zip(reference.xy, reference.theta, strict=True):
        dist = np.hypot(*(ours.xy - xy).T) if len(ours) else np.zeros(0)
        dtheta = np.degrees(np.abs((ours.theta - theta + np.pi) % (2 * np.pi) - np.pi)) if len(ours) else dist
        ok = (dist <= max_dist) & (dtheta <= max_angle_deg)
        if not ok.any():
            out.append(None)
            continue
        best = int(np.argmin(np.where(ok, dist, np.inf)))
        out.append((float(dist[best]), float(dtheta[best])))
    return out
