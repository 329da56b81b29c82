"""The map's own look-alikes: places whose walls around them match the walls around a given place.

A localizer can only rule out the places it is offered, and a twin place that lost its particles is offered by
nothing the robot saw. The walls of the map say where such twins are, whatever the robot saw: this module takes
the wall cells within ``radius_m`` of a place, turns them by every ``angle_step_deg`` and slides them over the
map's walls (one FFT correlation per angle, at ``resolution_m``), and returns the poses where at least
``min_overlap`` of them land on walls there. A robot at a twin sees what it would see at the place. Results are
kept per ``cell_m`` cell of the map. PIMM's ambiguity check, its bounds and its active guide use it.

Working out one cell takes tens of milliseconds (36 FFT correlations), too long for a localizer's update on a
robot: ``world prepare`` works out every cell with free space once and writes the table beside the other derived
maps (``twins.npz``, ``save``); ``load`` takes it back when it was made from the same map and settings, and a cell
it lacks is worked out as before.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy import ndimage

from pimm_env.errors import LocalizerError
from pimm_env.geometry import wrap_angle
from pimm_env.mapping.occupancy import OccupancyGrid
from pimm_env.world.model import World


@dataclass(frozen=True)
class TwinConfig:
    """How the map is searched for twins (ours; measured, docs/design.md#the-maps-twins)."""

    radius_m: float = 8.0  # the surroundings compared: about what the ambiguity check's kept scans span
    resolution_m: float = 0.25  # the map is compared at this cell size; walls count within one cell
    angle_step_deg: float = 10.0  # a divisor of 90, so that a building's own axes are among the turns
    min_overlap: float = 0.6  # share of the place's wall cells that must land on walls at a twin
    #: the best-matching twins kept (None: all; at least 1.5 m apart, or turned apart: below). PIMM's check keeps
    #: all: a twin left out is a place it cannot rule out, and a floor of repeated rooms along corridors has
    #: hundreds per place (median 191, at most 471 on a real KTH floor), the true one ranked 70th by its overlap
    max_twins: int | None = None
    #: two matches less than 1.5 m apart are one twin unless their turns differ by more than this (180: position
    #: alone decides, as the ambiguity check was measured; the bounds use 30)
    distinct_turn_deg: float = 180.0
    cell_m: float = 1.0  # twins are worked out once per cell of this size and carried to poses inside it

    def __post_init__(self) -> None:
        if self.radius_m <= 0 or self.resolution_m <= 0 or self.cell_m <= 0:
            raise LocalizerError("twins: radius_m, resolution_m and cell_m must be positive")
        if not 0 < self.angle_step_deg <= 90 or 90 % self.angle_step_deg:
            raise LocalizerError(f"twins: angle_step_deg must divide 90, got {self.angle_step_deg}")
        if not 0 <= self.distinct_turn_deg <= 180:
            raise LocalizerError(f"twins: distinct_turn_deg must lie in [0, 180], got {self.distinct_turn_deg}")
        if not 0 < self.min_overlap <= 1 or (self.max_twins is not None and self.max_twins < 0):
            raise LocalizerError("twins: min_overlap must lie in (0, 1], max_twins >= 0 (or None: all)")


class MapTwins:
    """Twins of places in one map. Walls are the occupied cells that free space can see (a solid block counts by
    its faces only, so the mass outside a building does not swamp the walls inside it)."""

    def __init__(self, occupancy: OccupancyGrid, config: TwinConfig) -> None:
        self.config = config
        grid = occupancy.grid
        self.grid = grid
        self.free = occupancy.free
        factor = max(1, round(config.resolution_m / grid.resolution))
        self.resolution = grid.resolution * factor
        rows, cols = (-(-grid.shape[0] // factor), -(-grid.shape[1] // factor))
        walls = np.zeros((rows * factor, cols * factor), dtype=bool)
        walls[: grid.shape[0], : grid.shape[1]] = occupancy.surfaces()
        #: wall cells at the coarse size, and the same grown by a cell: where a turned wall cell may land
        self.walls = walls.reshape(rows, factor, cols, factor).any(axis=(1, 3))
        target = ndimage.binary_dilation(self.walls, structure=np.ones((3, 3), dtype=bool))
        self._reach = int(np.ceil(config.radius_m / self.resolution))
        self._shape = (rows + 2 * self._reach + 1, cols + 2 * self._reach + 1)
        padded = np.zeros(self._shape)
        padded[self._reach : self._reach + rows, self._reach : self._reach + cols] = target
        self._target_fft = np.fft.rfft2(padded)
        self._cache: dict[tuple[int, int], np.ndarray] = {}

    def signature(self) -> str:
        """What the twins depend on: the settings and the map's walls and free space (a table made from another
        map or other settings is not taken)."""
        digest = hashlib.sha256(repr(self.config).encode())
        digest.update(repr((self.grid.origin, self.grid.resolution, self.grid.shape)).encode())
        digest.update(np.packbits(self.walls).tobytes())
        digest.update(np.packbits(self.free).tobytes())
        return digest.hexdigest()[:16]

    def free_cells(self) -> list[tuple[int, int]]:
        """Every ``cell_m`` cell holding free space: the cells a localizer's estimate can ask about."""
        rows, cols = np.nonzero(self.free)
        x = self.grid.origin[0] + (cols + 0.5) * self.grid.resolution
        y = self.grid.origin[1] + (rows + 0.5) * self.grid.resolution
        cells = np.unique(np.column_stack([np.floor(x / self.config.cell_m), np.floor(y / self.config.cell_m)]), axis=0)
        return [(int(i), int(j)) for i, j in cells]

    def precompute(self, progress: bool = False) -> int:
        """Work out the twins of every cell with free space now; returns how many cells were worked out."""
        cells = [key for key in self.free_cells() if key not in self._cache]
        if progress:
            from tqdm import tqdm

            cells = tqdm(cells, desc="map twins", unit="cell", leave=False)  # type: ignore[assignment]
        for key in cells:
            self.of(np.array([(key[0] + 0.5) * self.config.cell_m, (key[1] + 0.5) * self.config.cell_m, 0.0]))
        return len(cells)

    def save(self, path: Path) -> Path:
        """The table of every cell worked out so far, with the signature it holds for."""
        keys = sorted(self._cache)
        counts = np.array([len(self._cache[k]) for k in keys], dtype=np.int64)
        rows = np.vstack([self._cache[k] for k in keys]).reshape(-1, 5) if keys else np.zeros((0, 5))
        np.savez_compressed(
            path, signature=np.array(self.signature()), keys=np.array(keys, dtype=np.int64).reshape(-1, 2),
            counts=counts, rows=rows,
        )  # fmt: skip
        return Path(path)

    def load(self, path: Path) -> bool:
        """Take the table at ``path`` if it was made from this map and these settings; whether it was."""
        if not Path(path).is_file():
            return False
        with np.load(path, allow_pickle=False) as data:
            if str(data["signature"]) != self.signature():
                return False
            starts = np.concatenate([[0], np.cumsum(data["counts"])])
            rows = data["rows"]
            for k, key in enumerate(data["keys"]):
                self._cache[(int(key[0]), int(key[1]))] = rows[starts[k] : starts[k + 1]]
        return True

    def cell_of(self, pose: np.ndarray) -> tuple[int, int]:
        """The ``cell_m`` cell whose twins ``of`` gives for ``pose``."""
        return (int(np.floor(pose[0] / self.config.cell_m)), int(np.floor(pose[1] / self.config.cell_m)))

    def of(self, pose: np.ndarray) -> np.ndarray:
        """Twin poses (K, 3) of ``pose`` (x, y, heading), best match first; none where the place sees too few
        walls to compare."""
        c = self.config
        if c.max_twins == 0:
            return np.zeros((0, 3))
        key = self.cell_of(pose)
        if key not in self._cache:
            self._cache[key] = self._twins_at(np.array([(key[0] + 0.5) * c.cell_m, (key[1] + 0.5) * c.cell_m]))
        found = self._cache[key]  # (K, 5): centre x, y, turn, the cell centre's x, y
        if not len(found):
            return np.zeros((0, 3))
        turn = found[:, 2]
        dx, dy = pose[0] - found[:, 3], pose[1] - found[:, 4]
        cos, sin = np.cos(turn), np.sin(turn)
        return np.column_stack(
            [found[:, 0] + cos * dx - sin * dy, found[:, 1] + sin * dx + cos * dy, wrap_angle(pose[2] + turn)]
        )

    def _twins_at(self, centre: np.ndarray) -> np.ndarray:
        c, res, reach = self.config, self.resolution, self._reach
        ys, xs = np.nonzero(self.walls)
        wx = self.grid.origin[0] + (xs + 0.5) * res - centre[0]
        wy = self.grid.origin[1] + (ys + 0.5) * res - centre[1]
        near = wx**2 + wy**2 <= c.radius_m**2
        wx, wy = wx[near], wy[near]
        if len(wx) < 2 * c.radius_m / res:  # fewer wall cells than one wall across the surroundings
            return np.zeros((0, 5))
        peaks: list[tuple[float, float, float, float]] = []
        for turn in np.radians(np.arange(0.0, 360.0, c.angle_step_deg)):
            cos, sin = np.cos(turn), np.sin(turn)
            u = np.rint((cos * wx - sin * wy) / res).astype(int) + reach
            v = np.rint((sin * wx + cos * wy) / res).astype(int) + reach
            kernel = np.zeros(self._shape)
            kernel[v, u] = 1.0
            count = kernel.sum()
            score = np.fft.irfft2(self._target_fft * np.conj(np.fft.rfft2(kernel)), s=self._shape) / count
            score = score[: self.walls.shape[0], : self.walls.shape[1]]  # score[r, q]: the place at cell (r, q)
            for r, q in zip(*local_peaks(score, c.min_overlap), strict=True):
                x = self.grid.origin[0] + (q + 0.5) * res
                y = self.grid.origin[1] + (r + 0.5) * res
                peaks.append((float(score[r, q]), x, y, float(turn)))
        kept: list[tuple[float, float, float]] = []
        apart = np.radians(c.distinct_turn_deg)
        for _, x, y, turn in sorted(peaks, reverse=True):
            if np.hypot(x - centre[0], y - centre[1]) < 1.5 and abs(wrap_angle(turn)) < np.radians(c.angle_step_deg):
                continue  # the place itself
            if not self._free_at(x, y) or any(
                np.hypot(x - a, y - b) < 1.5 and abs(wrap_angle(turn - t)) <= apart for a, b, t in kept
            ):
                continue
            kept.append((x, y, turn))
            if c.max_twins is not None and len(kept) == c.max_twins:
                break
        return np.array([[x, y, t, centre[0], centre[1]] for x, y, t in kept]).reshape(-1, 5)

    def _free_at(self, x: float, y: float) -> bool:
        rows, cols, valid = self.grid.cells_of(np.array([[x, y]]))
        return bool(valid[0] and self.free[rows[0], cols[0]])


#: The table of a world's twins (PIMM's settings), beside its other derived maps.
TWINS_FILE = "twins.npz"


def world_twins(world: World, occupancy: OccupancyGrid) -> tuple[MapTwins, Path | None]:
    """PIMM's twins of ``world``'s map (``occupancy``), with the table `world prepare` wrote beside it taken where
    it was made from this map and these settings; and that table's path where one is there but was not taken."""
    from pimm_env.world.files import world_dir

    twins = MapTwins(occupancy, TwinConfig())
    table = world_dir(world) / TWINS_FILE
    return twins, None if twins.load(table) or not table.is_file() else table


def local_peaks(score: np.ndarray, floor: float, size: int = 5) -> tuple[np.ndarray, np.ndarray]:
    """Rows and columns (row-major order) of the cells of ``score`` at ``floor`` or above that equal the largest
    value of the ``size`` x ``size`` window about them (cut at the array's edge): the cells where
    ``(score >= floor) & (score == ndimage.maximum_filter(score, size))`` holds, worked out at those cells only
    (the filter over the whole map was a quarter of a twin search, for the few cells above ``floor``)."""
    rows, cols = np.nonzero(score >= floor)
    if not len(rows):
        return rows, cols
    half = size // 2
    padded = np.pad(score, half, constant_values=-np.inf)
    windows = np.lib.stride_tricks.sliding_window_view(padded, (size, size))[rows, cols]
    peak = score[rows, cols] == windows.max(axis=(1, 2))
    return rows[peak], cols[peak]
