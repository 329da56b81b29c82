"""Read a ROS map_server map (``.yaml`` + ``.pgm``/``.png``) as ROS does: thresholds, ``negate``, ``mode``,
and an ``origin`` that may carry a yaw.

The map_server YAML fields (nav2 ``map_server``, ROS 1 ``map_server``): ``image``, ``resolution``,
``origin: [x, y, yaw]`` (the pose of the lower-left pixel), ``negate``, ``occupied_thresh``, ``free_thresh``,
``mode`` (``trinary``, ``scale`` or ``raw``). A pixel's occupancy is ``p = (255 - v) / 255`` (``v / 255``
with ``negate``); ``p > occupied_thresh`` is occupied, ``p < free_thresh`` free, anything else unknown.
In ``raw`` mode the value itself is the occupancy in percent.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from pimm_env.errors import MapFileError, MissingFileError
from pimm_env.mapping.occupancy import OccupancyGrid, read_pgm


@dataclass(frozen=True)
class RasterMap:
    """Occupied and free cells of a map, row 0 at the bottom (+y up), with the map frame of its lower-left
    corner: a cell (row, col) has its centre at ``origin + R(yaw) ((col + 0.5) res, (row + 0.5) res)``."""

    occupied: np.ndarray
    free: np.ndarray
    resolution: float
    origin: tuple[float, float, float]  # x, y, yaw
    source: Path

    def to_map(self, points: np.ndarray) -> np.ndarray:
        """Image-frame points (x right, y up, metres from the lower-left corner) in the map frame."""
        x0, y0, yaw = self.origin
        c, s = np.cos(yaw), np.sin(yaw)
        points = np.asarray(points, dtype=float).reshape(-1, 2)
        return np.column_stack([x0 + c * points[:, 0] - s * points[:, 1], y0 + s * points[:, 0] + c * points[:, 1]])


def _number(meta: Mapping[str, Any], key: str, path: Path, default: float | None = None) -> float:
    value = meta.get(key, default)
    if isinstance(value, str):  # YAML 1.1 reads 1e-2 (no dot) as text; ROS's YAML reader takes it as a number
        try:
            value = float(value)
        except ValueError:
            pass
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not np.isfinite(value):
        raise MapFileError(f"{path}: {key}: expected a finite number, got {value!r}")
    return float(value)


def read_image(path: Path) -> np.ndarray:
    """8-bit grey pixels of a PGM (P5) or PNG, top row first; colour PNGs are averaged over RGB, 16-bit ones scaled
    to 8 bits (as map_server reads them: 254 of 65 535 is near black)."""
    if not path.is_file():
        raise MissingFileError(path)
    if path.suffix.lower() == ".pgm":
        return read_pgm(path)
    from PIL import Image

    with Image.open(path) as image:
        sixteen_bits = image.mode.startswith("I")  # a 16-bit grey PNG: map_server scales it to its full range
        pixels = np.asarray(image.convert("RGBA") if image.mode in ("P", "LA") else image)
    if pixels.ndim == 3:  # RGB(A): the mean of the colour channels, as map_server does
        pixels = pixels[..., :3].mean(axis=2)
    if sixteen_bits:
        pixels = np.round(np.clip(pixels, 0, 65535) / 257.0)
    elif pixels.dtype != np.uint8:
        pixels = np.clip(pixels, 0, 255)
    return pixels.astype(np.uint8)


def read_ros_map(yaml_path: Path) -> RasterMap:
    """The map at ``yaml_path``; every problem names the file and the field."""
    from pimm_env.yaml_file import read_yaml_mapping

    yaml_path = Path(yaml_path)
    meta = read_yaml_mapping(yaml_path, "map_server map (image, resolution, origin, ...)", MapFileError)
    image_name = meta.get("image")
    if not isinstance(image_name, str) or not image_name:
        raise MapFileError(f"{yaml_path}: image: expected the image file's name, got {image_name!r}")
    image_path = (yaml_path.parent / image_name).resolve()
    resolution = _number(meta, "resolution", yaml_path)
    if not 1e-4 <= resolution <= 10.0:
        raise MapFileError(
            f"{yaml_path}: resolution: expected metres per pixel (a positive number up to 10), got {resolution}"
        )
    origin = meta.get("origin")
    if not isinstance(origin, list) or len(origin) not in (2, 3):
        raise MapFileError(f"{yaml_path}: origin: expected [x, y, yaw], got {origin!r}")
    ox, oy, yaw = (_number({"origin": v}, "origin", yaml_path) for v in [*origin, 0.0][:3])
    occupied_thresh = _number(meta, "occupied_thresh", yaml_path, 0.65)
    free_thresh = _number(meta, "free_thresh", yaml_path, 0.196)
    if not 0 <= free_thresh <= occupied_thresh <= 1:
        raise MapFileError(
            f"{yaml_path}: free_thresh {free_thresh} and occupied_thresh {occupied_thresh}: "
            "expected 0 <= free_thresh <= occupied_thresh <= 1"
        )
    mode = meta.get("mode", "trinary")
    if mode not in ("trinary", "scale", "raw"):
        raise MapFileError(f"{yaml_path}: mode: expected trinary, scale or raw, got {mode!r}")
    negate = meta.get("negate", 0)
    if negate not in (0, 1, True, False):
        raise MapFileError(f"{yaml_path}: negate: expected 0 or 1, got {negate!r}")
    try:
        pixels = np.flipud(read_image(image_path)).astype(float)
    except FileNotFoundError:
        raise MapFileError(f"{yaml_path}: image: file {image_path} does not exist") from None
    except (ValueError, OSError) as error:
        raise MapFileError(f"{yaml_path}: image: cannot read {image_path}: {error}") from None
    if mode == "raw":  # the value is the occupancy in percent; above 100 (255: -1) is unknown
        probability = np.where(pixels > 100, np.nan, pixels / 100.0)
    else:
        probability = pixels / 255.0 if negate else (255.0 - pixels) / 255.0
    return RasterMap(probability > occupied_thresh, probability < free_thresh, resolution, (ox, oy, yaw), yaml_path)


def load_map_server(yaml_path: Path, require_free: bool = True) -> OccupancyGrid:
    """A map_server map (PGM or PNG, thresholds, ``negate`` and ``mode`` honoured) as an occupancy grid: the
    derived maps of a world, or the map a map-only localizer runs on. The grid is axis-aligned: an origin yaw
    other than 0 is refused (nav2's amcl ignores it; we say so instead)."""
    from pimm_env.world.grid import GridSpec

    raster = read_ros_map(yaml_path)
    x0, y0, yaw = raster.origin
    if abs(yaw) > 1e-9:
        raise MapFileError(
            f"{yaml_path}: origin: yaw {yaw} rad; an occupancy grid here is axis-aligned (yaw 0). "
            "Import it as a world instead: python evaluate.py world import MAP.yaml --name NAME"
        )
    if require_free and not raster.free.any():
        raise MapFileError(f"{yaml_path}: the map has no free cell (check negate and the thresholds)")
    return OccupancyGrid(GridSpec((x0, y0), raster.resolution, raster.occupied.shape), raster.occupied, raster.free)
