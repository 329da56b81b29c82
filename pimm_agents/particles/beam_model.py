"""nav2_amcl's beam model (``laser_model_type: beam``; Probabilistic Robotics 6.3): each beam's measured range
against the range the map gives along it from the particle.

pz = z_hit exp(-(z - z*)^2 / 2 sigma_hit^2)                      a hit, noisy
   + z_short lambda_short exp(-lambda_short z)   if z < z*      something unmapped in front
   + z_max                                       if z = max     no return
   + z_rand / range_max                          if z < max     anything

and a particle's weight factor is 1 + sum of pz^3 over the beams, as nav2 sums it. Expected ranges come from
ray casting in the map as nav2's ``map_calc_range`` does: a ray stops at the first cell that is occupied,
unknown or off the map. Two ways to get them, instead of nav2's cell-by-cell Bresenham walk for every beam of
every particle:

- ``RangeTable`` (the default): the ranges from every free cell's centre at a fixed set of headings, cast once
  per map and looked up per beam (range_libc's lookup-table method). nav2 itself casts from the particle's
  cell, so the position is as nav2 has it; the heading is rounded to the table's step (1 degree by default, a
  few centimetres at 10 m) and the range to a cell. 2 000 particles x 60 beams cost a gather.
- ``RangeCaster``: exact rays from the particle's position along the beam's own heading, all beams of an update
  cast together with Embree against the free space's boundary; ~20x slower than the table.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass

import numpy as np

from pimm_env.errors import LocalizerError
from pimm_env.mapping.occupancy import OccupancyGrid


@dataclass(frozen=True)
class BeamModelParams:
    """nav2_amcl's defaults."""

    z_hit: float = 0.5
    z_short: float = 0.05
    z_max: float = 0.05
    z_rand: float = 0.5
    sigma_hit: float = 0.2
    lambda_short: float = 0.1

    def __post_init__(self) -> None:
        if self.sigma_hit <= 0 or self.lambda_short <= 0:
            raise LocalizerError(f"sigma_hit and lambda_short must be positive: {self}")


def beam_probabilities(
    measured: np.ndarray, expected: np.ndarray, range_max: float, params: BeamModelParams = BeamModelParams()
) -> np.ndarray:
    """pz of each beam (any shape, ``measured`` broadcast against ``expected``) as nav2's ``BeamModel`` adds
    it up; a measured range of ``range_max`` or more is a max-range reading."""
    p = params
    z = measured - expected
    pz = p.z_hit * np.exp(-(z * z) / (2 * p.sigma_hit**2))
    pz = pz + np.where(z < 0, p.z_short * p.lambda_short * np.exp(-p.lambda_short * measured), 0.0)
    is_max = measured >= range_max
    return pz + np.where(is_max, p.z_max, p.z_rand / range_max)


def boundary_faces(free: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The edges between free cells and the rest (occupied, unknown, off the map), in cell units: (start,
    end) corner points (E, 2) and (E, 2) as (col, row) with cell (r, c) spanning [c, c + 1] x [r, r + 1]."""
    padded = np.zeros((free.shape[0] + 2, free.shape[1] + 2), dtype=bool)  # off the map stops rays
    padded[1:-1, 1:-1] = free
    # between horizontal neighbours (r, c) | (r, c + 1) of the padded grid: the line x = c (unpadded)
    r, c = np.nonzero(padded[:, :-1] != padded[:, 1:])
    vertical_a = np.stack([c, r - 1], axis=1)
    vertical_b = np.stack([c, r], axis=1)
    # between vertical neighbours (r, c) / (r + 1, c): the line y = r
    r, c = np.nonzero(padded[:-1, :] != padded[1:, :])
    horizontal_a = np.stack([c - 1, r], axis=1)
    horizontal_b = np.stack([c, r], axis=1)
    return (np.vstack([vertical_a, horizontal_a]).astype(float), np.vstack([vertical_b, horizontal_b]).astype(float))


def sensor_positions(poses: np.ndarray, origin: tuple[float, float]) -> np.ndarray:
    """(N, 2) map positions of a sensor mounted at ``origin`` (robot frame) on each pose (N, 3)."""
    c, s = np.cos(poses[:, 2]), np.sin(poses[:, 2])
    return np.stack([poses[:, 0] + c * origin[0] - s * origin[1], poses[:, 1] + s * origin[0] + c * origin[1]], 1)


class RangeCaster:
    """Ranges along rays in an occupancy grid to the first cell that is not free (nav2's ``map_calc_range``:
    occupied, unknown or off the map), capped at ``range_max``.

    Where nav2 walks each ray cell by cell, we build the boundary of the free space once as vertical faces
    and cast all rays of an update together with Open3D's ``RaycastingScene`` (Embree); the range is to the
    cell's edge rather than to its centre, a difference under one cell.
    """

    def __init__(self, occupancy: OccupancyGrid, range_max: float) -> None:
        import open3d as o3d

        if range_max <= 0:
            raise LocalizerError(f"range_max must be positive, got {range_max}")
        self.grid = occupancy.grid
        self.range_max = float(range_max)
        a, b = boundary_faces(occupancy.free)
        res, (x0, y0) = self.grid.resolution, self.grid.origin
        a = a * res + (x0, y0)
        b = b * res + (x0, y0)
        n = len(a)
        vertices = np.empty((4 * n, 3), dtype=np.float32)
        vertices[0::4, :2], vertices[0::4, 2] = a, -1.0
        vertices[1::4, :2], vertices[1::4, 2] = b, -1.0
        vertices[2::4, :2], vertices[2::4, 2] = b, 1.0
        vertices[3::4, :2], vertices[3::4, 2] = a, 1.0
        base = 4 * np.arange(n, dtype=np.uint32)[:, None]
        triangles = np.vstack([base + np.array([0, 1, 2], np.uint32), base + np.array([0, 2, 3], np.uint32)])
        self._inside = occupancy.free
        self.scene = o3d.t.geometry.RaycastingScene()
        self.scene.add_triangles(o3d.core.Tensor.from_numpy(vertices), o3d.core.Tensor.from_numpy(triangles))

    def ranges(self, poses: np.ndarray, bearings: np.ndarray, origin: tuple[float, float] = (0.0, 0.0)) -> np.ndarray:
        """(N, B) ranges (m) from each pose's sensor (at ``origin`` in the robot frame) along each bearing; 0
        from a sensor that is not in a free cell."""
        import open3d as o3d

        poses = np.asarray(poses, dtype=np.float64).reshape(-1, 3)
        bearings = np.asarray(bearings, dtype=np.float64).ravel()
        sensor = sensor_positions(poses, origin)
        sx, sy = sensor.T
        angle = poses[:, 2:3] + bearings[None, :]
        rays = np.zeros((len(poses), len(bearings), 6), dtype=np.float32)
        rays[:, :, 0], rays[:, :, 1] = sx[:, None], sy[:, None]
        rays[:, :, 3], rays[:, :, 4] = np.cos(angle), np.sin(angle)
        hit = self.scene.cast_rays(o3d.core.Tensor.from_numpy(rays.reshape(-1, 6)))["t_hit"].numpy()
        ranges = np.minimum(hit.reshape(len(poses), len(bearings)).astype(np.float64), self.range_max)
        rows, cols, valid = self.grid.cells_of(sensor)
        inside = np.zeros(len(poses), dtype=bool)
        inside[valid] = self._inside[rows[valid], cols[valid]]
        ranges[~inside] = 0.0  # nav2: a ray that starts in a blocked cell stops there
        return ranges


class RangeTable:
    """Expected ranges looked up instead of cast: for every free cell and each of ``headings`` evenly spaced
    directions, the range from the cell's centre to the first cell that is not free (``RangeCaster``, cast
    once), stored in whole cells. A beam from a pose takes the entry of the cell its sensor is in and of the
    nearest heading. Memory: free cells x headings x 1 byte (2 where ``range_max`` spans over 255 cells), e.g.
    61 MB for the iilab's 169 000 free cells at 360 headings."""

    def __init__(self, occupancy: OccupancyGrid, range_max: float, headings: int = 360) -> None:
        if headings < 4:
            raise LocalizerError(f"RangeTable needs at least 4 headings, got {headings}")
        caster = RangeCaster(occupancy, range_max)
        self.grid, self.range_max, self.headings = caster.grid, caster.range_max, int(headings)
        rows, cols = np.nonzero(occupancy.free)
        self._row_of_cell = np.full(occupancy.free.shape, -1, dtype=np.int64)
        self._row_of_cell[rows, cols] = np.arange(len(rows))
        res, (x0, y0) = self.grid.resolution, self.grid.origin
        centres = np.stack([x0 + (cols + 0.5) * res, y0 + (rows + 0.5) * res, np.zeros(len(rows))], axis=1)
        cells_max = int(np.ceil(self.range_max / res))
        dtype = np.uint8 if cells_max <= np.iinfo(np.uint8).max else np.uint16
        self.table = np.empty((len(rows), self.headings), dtype=dtype)
        step = 2 * np.pi / self.headings
        for k in range(self.headings):  # one heading at a time keeps the rays' memory small
            cast = caster.ranges(centres, np.array([k * step]))[:, 0]
            self.table[:, k] = np.rint(cast / res).astype(dtype)
        self.max_cells = int(self.table.max()) if self.table.size else 0

    def cells(self, poses: np.ndarray, bearings: np.ndarray, origin: tuple[float, float] = (0.0, 0.0)) -> np.ndarray:
        """(N, B) ranges in whole cells (int32) from each pose's sensor along each bearing; 0 from a sensor
        that is not in a free cell (nav2: a ray that starts in a blocked cell stops there)."""
        poses = np.asarray(poses, dtype=np.float64).reshape(-1, 3)
        bearings = np.asarray(bearings, dtype=np.float64).ravel()
        rows, cols, valid = self.grid.cells_of(sensor_positions(poses, origin))
        index = np.full(len(poses), -1, dtype=np.int64)
        index[valid] = self._row_of_cell[rows[valid], cols[valid]]
        # the nearest heading, in float32 and int32 (the table's 61 million entries fit): this is the hot loop
        per_radian = self.headings / (2 * np.pi)
        own = (np.mod(poses[:, 2], 2 * np.pi) * per_radian).astype(np.float32)
        beam = (np.mod(bearings, 2 * np.pi) * per_radian).astype(np.float32)
        flat = (own[:, None] + beam[None, :] + np.float32(0.5)).astype(np.int32)
        flat %= self.headings
        flat += (np.maximum(index, 0) * self.headings).astype(np.int32)[:, None]
        cells = np.take(self.table, flat).astype(np.int32)
        cells[index < 0] = 0
        return cells

    def ranges(self, poses: np.ndarray, bearings: np.ndarray, origin: tuple[float, float] = (0.0, 0.0)) -> np.ndarray:
        """(N, B) ranges (m) as ``RangeCaster.ranges`` gives them, from the table."""
        return np.minimum(self.cells(poses, bearings, origin) * self.grid.resolution, self.range_max)


_TABLES: dict[tuple[str, float, int], RangeTable] = {}


def shared_range_table(occupancy: OccupancyGrid, range_max: float, headings: int) -> RangeTable:
    """One ``RangeTable`` per map, range and heading count in this process (building one casts a ray per free
    cell and heading: ~60 million for the iilab, tens of seconds), reused by every filter made on that map."""
    digest = hashlib.sha1(np.packbits(occupancy.free).tobytes())
    digest.update(np.asarray([*occupancy.grid.origin, occupancy.grid.resolution, *occupancy.free.shape]).tobytes())
    key = (digest.hexdigest(), float(range_max), int(headings))
    if key not in _TABLES:
        if len(_TABLES) >= 2:  # a process evaluates one or two maps; keep memory bounded
            _TABLES.pop(next(iter(_TABLES)))
        _TABLES[key] = RangeTable(occupancy, range_max, headings)
    return _TABLES[key]


class BeamModel:
    """nav2's beam model over an occupancy grid: weight factors for many poses at once. ``headings`` > 0
    looks expected ranges up in a ``RangeTable`` of that many directions; 0 casts them exactly."""

    def __init__(
        self,
        occupancy: OccupancyGrid,
        range_max: float,
        params: BeamModelParams = BeamModelParams(),
        headings: int = 360,
    ) -> None:
        self.params = params
        self.caster: RangeTable | RangeCaster = (
            shared_range_table(occupancy, range_max, headings) if headings > 0 else RangeCaster(occupancy, range_max)
        )

    def weight_factors(
        self, poses: np.ndarray, ranges: np.ndarray, bearings: np.ndarray, origin: tuple[float, float] = (0.0, 0.0)
    ) -> np.ndarray:
        """1 + sum over the beams of pz^3, for each pose (N, 3); ``ranges`` at or over range_max are no-returns."""
        if np.size(ranges) == 0:
            return np.ones(len(poses))
        measured = np.minimum(np.asarray(ranges, dtype=np.float64), self.caster.range_max)
        if isinstance(self.caster, RangeCaster):
            expected = self.caster.ranges(poses, bearings, origin)
            pz = beam_probabilities(measured[None, :], expected, self.caster.range_max, self.params)
            return 1.0 + (pz**3).sum(axis=1)
        # the table's ranges are whole cells: pz^3 of every beam at every possible cell count, then a gather
        table = self.caster
        counts = np.arange(table.max_cells + 1)
        expected = np.minimum(counts * table.grid.resolution, table.range_max)
        pz3 = beam_probabilities(measured[:, None], expected[None, :], table.range_max, self.params) ** 3
        cells = table.cells(poses, bearings, origin)
        cells += (np.arange(len(measured), dtype=np.int32) * len(counts))[None, :]
        return 1.0 + np.take(pz3, cells).sum(axis=1)
