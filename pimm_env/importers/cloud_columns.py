"""Which voxels of a levelled cloud map are floor, ceiling, wall or clutter, judged column by column (a column:
the voxels over one cell of the floor plan).

- **floor**: within ``floor_band_m`` of the floor;
- **ceiling**: in a column rising at least ``ceiling_min_m``, within ``ceiling_band_m`` of its top (each column at
  its own height: a real ceiling is not flat);
- **wall**: a column whose voxels stand stacked from ``wall_from_m`` (above desks and chairs, which hide a wall's
  foot) to near its ceiling, over at least ``wall_min_span_m`` and with gaps no wider than ``wall_gap_m`` (a wall
  seen from afar shows only the LiDAR's rings). Its ceiling is its own top or, lower, a ceiling over open floor
  beside it that it holds up: a wall going on over a suspended ceiling is seen up there only from afar, through
  gaps;
- **clutter**: the rest.
"""

from __future__ import annotations

from typing import Any

import numpy as np

#: The surface classes of a cloud map's voxels, in the order of ``CLASSES`` indices.
CLASSES = ("floor", "ceiling", "wall", "clutter")
FLOOR, CEILING, WALL, CLUTTER = range(4)


def column_classes(voxels: np.ndarray, config: Any) -> tuple[np.ndarray, np.ndarray]:
    """Each voxel's class (an index into ``CLASSES``) and its column's top height, by the rules of the module's
    text. ``config``: cloud_map.CloudMapConfig."""
    v = config.voxel_m
    z = (voxels[:, 2] + 0.5) * v
    classes = np.full(len(voxels), CLUTTER, dtype=np.int8)
    column, inverse = np.unique(voxels[:, :2], axis=0, return_inverse=True)
    inverse = inverse.reshape(-1)
    top = np.full(len(column), -np.inf)
    np.maximum.at(top, inverse, z)
    above_floor = z > config.floor_band_m
    # a wall is judged on its upper part, above desks and chairs, which hide its foot from a LiDAR, up to its own
    # ceiling or a lower one beside it that it holds up (over that, it is seen only from afar: through gaps)
    wall_column = np.zeros(len(column), dtype=bool)
    for up_to in (top, np.minimum(top, _ceiling_beside(column, top, inverse, z, config))):
        held = up_to - config.ceiling_band_m
        band = above_floor & (z >= config.wall_from_m) & (z < held[inverse])
        wall_column |= _stacked(inverse[band], z[band], len(column), config.wall_from_m, held, config)
    ceiling = (top[inverse] >= config.ceiling_min_m) & (z >= top[inverse] - config.ceiling_band_m)
    classes[wall_column[inverse] & above_floor] = WALL
    classes[ceiling & above_floor] = CEILING  # a wall's column ends in the ceiling it holds up
    classes[~above_floor] = FLOOR
    return classes, top[inverse]


def _ceiling_beside(column: np.ndarray, top: np.ndarray, inverse: np.ndarray, z: np.ndarray, config: Any) -> np.ndarray:
    """Each of the ``column`` s' lowest ceiling within two columns (inf where none): the top (``top``: each
    column's highest voxel's height) of a column over open floor (floor seen, less than half its height under the
    ceiling band occupied: not a cabinet's side nor a wall), level with three of its neighbours (a ceiling is a
    level surface; a sparsely seen wall's inside is not) and high enough to be a wall's ceiling."""
    from scipy import ndimage

    v = config.voxel_m
    lo = column.min(axis=0) - 1
    at = (column[:, 0] - lo[0], column[:, 1] - lo[1])
    grid = np.full(tuple(column.max(axis=0) - lo + 2), np.nan)
    grid[at] = top
    level = sum(
        np.abs(np.roll(grid, (dx, dy), axis=(0, 1)) - grid) < 1.5 * v
        for dx in (-1, 0, 1)
        for dy in (-1, 0, 1)
        if dx or dy
    )[at]
    floor = np.bincount(inverse, z <= config.floor_band_m, len(column)) > 0
    under = (z > config.floor_band_m) & (z < top[inverse] - config.ceiling_band_m)
    filled = np.bincount(inverse, under, len(column)) * v
    room = top - config.ceiling_band_m - config.floor_band_m
    lowest = config.wall_from_m + config.wall_min_span_m + config.ceiling_band_m  # the wall test's least top
    ceiling = floor & (level >= 3) & (top >= lowest) & (filled < room / 2)
    heights = np.full(grid.shape, np.inf)
    heights[at[0][ceiling], at[1][ceiling]] = top[ceiling]
    near = np.ones((5, 5), dtype=bool)  # within two columns: a wall's face spreads over one or two
    near[2, 2] = False
    return ndimage.minimum_filter(heights, footprint=near, mode="constant", cval=np.inf)[at]


def _stacked(column: np.ndarray, z: np.ndarray, columns: int, bottom: float, top: np.ndarray, config: Any):
    """Which of ``columns`` hold voxels (their ``column`` and heights ``z``) stacked from ``bottom`` to their
    ``top`` over at least ``wall_min_span_m``, no two (nor an end and its nearest) further apart than
    ``wall_gap_m``."""
    order = np.lexsort((z, column))
    column, z = column[order], z[order]
    low, high = np.full(columns, np.inf), np.full(columns, -np.inf)
    np.minimum.at(low, column, z - config.voxel_m / 2)
    np.maximum.at(high, column, z + config.voxel_m / 2)
    gap = np.zeros(columns)
    same = column[1:] == column[:-1]
    np.maximum.at(gap, column[1:][same], np.diff(z)[same] - config.voxel_m)
    gap = np.maximum(gap, np.maximum(low - bottom, top - high))
    return (high - low >= config.wall_min_span_m) & (gap <= config.wall_gap_m)
